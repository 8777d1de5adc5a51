//! The convex hull of a point cloud in space, its validation and its mass.
//!
//! The hull is built incrementally (Clarkson and Shor; the "beneath-beyond" method): start from
//! a tetrahedron of four extreme points, then add each remaining point that lies beyond some
//! face by removing the faces it sees and joining it to their horizon. Faces are triangles
//! wound counter-clockwise seen from outside; a point within the hull tolerance of a face is
//! on it and is dropped. A point added before the hull grew past it can end on a later face
//! or edge: a last pass drops every corner within the tolerance of the hull of the others, so
//! the vertices kept are the hull's corners.

use glam::{DMat3, DVec3, Mat3, Vec3};

use crate::geometry::constants::{
    HULL_RELATIVE_TOLERANCE, MAX_ASPECT_RATIO, MAX_HULL_INPUT_POINTS, MAX_HULL_VERTICES,
    MIN_SHAPE_SIZE,
};
use crate::geometry::shape::ShapeError;

/// A triangle of the hull: vertex indices (counter-clockwise from outside), its unit outward
/// normal and its plane offset (`normal · x = offset` on the plane).
#[derive(Clone, Copy, Debug)]
struct Face {
    v: [usize; 3],
    normal: Vec3,
    offset: f32,
}

impl Face {
    fn new(points: &[Vec3], v: [usize; 3]) -> Self {
        let [a, b, c] = v.map(|i| points[i]);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        Self {
            v,
            normal,
            offset: normal.dot(a),
        }
    }

    fn height(&self, p: Vec3) -> f32 {
        self.normal.dot(p) - self.offset
    }
}

/// The corners of the convex hull of `points` and the hull's triangles (indices into the
/// corners, counter-clockwise from outside), validated as a solid of some volume.
pub(crate) fn convex_hull(points: &[Vec3]) -> Result<(Vec<Vec3>, Vec<[usize; 3]>), ShapeError> {
    if points.len() < 4 {
        return Err(ShapeError::TooFewPoints);
    }
    if points.len() > MAX_HULL_INPUT_POINTS {
        return Err(ShapeError::TooManyInputPoints);
    }
    if points.iter().any(|p| !p.is_finite()) {
        return Err(ShapeError::NonFinite);
    }
    let tol = tolerance(points);
    let (faces, length) = hull_faces(points, tol)?;
    let (mut corners, mut faces) = used_corners(points, &faces);

    // A corner added before the hull grew past it can end on a face or an edge of the final
    // hull (within the tolerance); it changes no support point but is no corner. Drop each
    // corner that lies within the tolerance of the hull of the others, and start over after
    // each drop (the hull of the rest changed). Only a corner whose faces close flat around it
    // (the angles there sum to a full turn) can be such a point: the others are not rebuilt.
    'scan: loop {
        for j in 0..corners.len() {
            if angle_deficit(&corners, &faces, j) > FLAT_CORNER_DEFICIT {
                continue;
            }
            let mut others = corners.clone();
            let p = others.remove(j);
            if let Ok((rest, _)) = hull_faces(&others, tol)
                && rest.iter().all(|f| f.height(p) <= tol)
            {
                (corners, faces) = used_corners(&others, &rest);
                continue 'scan;
            }
        }
        break;
    }

    if corners.len() > MAX_HULL_VERTICES {
        return Err(ShapeError::TooManyPoints);
    }
    // Too thin: the hull's width (its least extent along a face normal) against its length.
    let width = faces
        .iter()
        .map(|f| {
            corners
                .iter()
                .map(|&p| -f.height(p))
                .fold(0.0_f32, f32::max)
        })
        .fold(f32::INFINITY, f32::min);
    if width < MIN_SHAPE_SIZE {
        return Err(ShapeError::Coplanar);
    }
    if length > MAX_ASPECT_RATIO * width {
        return Err(ShapeError::TooThin);
    }
    Ok((corners, faces.iter().map(|f| f.v).collect()))
}

/// The angle deficit (rad) below which a corner may lie on a face or an edge of the hull of
/// the others and is checked: such a point's faces close flat around it (deficit 0 but for
/// rounding, about 1e-6 in `f32`); a true corner with a smaller deficit (a very flat apex) is
/// checked too, and kept.
const FLAT_CORNER_DEFICIT: f32 = 1.0e-3;

/// A full turn less the angles of the faces at `corner`: the solid angle of its normal cone.
fn angle_deficit(corners: &[Vec3], faces: &[Face], corner: usize) -> f32 {
    let mut deficit = core::f32::consts::TAU;
    for f in faces {
        if let Some(k) = f.v.iter().position(|&v| v == corner) {
            let p = corners[corner];
            let (u, w) = (corners[f.v[(k + 1) % 3]] - p, corners[f.v[(k + 2) % 3]] - p);
            deficit -= u.cross(w).length().atan2(u.dot(w));
        }
    }
    deficit
}

/// The points `faces` use, in input order, and the faces renumbered to them.
fn used_corners(points: &[Vec3], faces: &[Face]) -> (Vec<Vec3>, Vec<Face>) {
    let mut index = vec![usize::MAX; points.len()];
    let mut corners = Vec::new();
    for (i, p) in points.iter().enumerate() {
        if faces.iter().any(|f| f.v.contains(&i)) {
            index[i] = corners.len();
            corners.push(*p);
        }
    }
    let faces = faces
        .iter()
        .map(|f| Face {
            v: f.v.map(|i| index[i]),
            ..*f
        })
        .collect();
    (corners, faces)
}

/// The hull's faces over `points` (indices into them) and the length of its longest
/// axis-extreme pair, or why the points span no solid.
fn hull_faces(points: &[Vec3], tol: f32) -> Result<(Vec<Face>, f32), ShapeError> {
    // The first two corners: the extreme pair along the axis of largest spread.
    let (lo, hi) = extreme_pair(points);
    let length = points[lo].distance(points[hi]);
    if length < MIN_SHAPE_SIZE.max(tol) {
        return Err(ShapeError::TooSmall);
    }
    // The third: farthest from the line of the first two.
    let axis = (points[hi] - points[lo]) / length;
    let (third, off_line) = farthest(points, |p| {
        let d = p - points[lo];
        (d - axis * d.dot(axis)).length()
    });
    if off_line <= tol.max(MIN_SHAPE_SIZE) {
        return Err(ShapeError::Collinear);
    }
    // The fourth: farthest from the plane of the first three.
    let plane = Face::new(points, [lo, hi, third]);
    let (fourth, off_plane) = farthest(points, |p| plane.height(p).abs());
    if off_plane <= tol.max(MIN_SHAPE_SIZE) {
        return Err(ShapeError::Coplanar);
    }

    let mut faces: Vec<Face> = Vec::with_capacity(64);
    let base = if plane.height(points[fourth]) > 0.0 {
        [lo, third, hi]
    } else {
        [lo, hi, third]
    };
    let [a, b, c] = base;
    for v in [[a, b, c], [a, fourth, b], [b, fourth, c], [c, fourth, a]] {
        faces.push(Face::new(points, v));
    }

    let mut visible = Vec::new();
    let mut edges: Vec<(usize, usize)> = Vec::new();
    for (i, &p) in points.iter().enumerate() {
        if [a, b, c, fourth].contains(&i) {
            continue;
        }
        visible.clear();
        visible.extend(faces.iter().map(|f| f.height(p) > tol));
        if !visible.contains(&true) {
            continue;
        }
        // The horizon: the edges of seen faces whose other face is not seen, kept in the
        // seen face's winding so that the new faces wind the same way.
        edges.clear();
        for (f, _) in faces.iter().zip(&visible).filter(|(_, seen)| **seen) {
            for k in 0..3 {
                edges.push((f.v[k], f.v[(k + 1) % 3]));
            }
        }
        let horizon: Vec<(usize, usize)> = edges
            .iter()
            .copied()
            .filter(|&(u, w)| !edges.contains(&(w, u)))
            .collect();
        let mut seen = visible.iter();
        faces.retain(|_| !*seen.next().unwrap_or(&false));
        for (u, w) in horizon {
            faces.push(Face::new(points, [u, w, i]));
        }
    }
    Ok((faces, length))
}

/// The distance below which a point is on a face: [`HULL_RELATIVE_TOLERANCE`] of the cloud's
/// extent, or of a tenth of its distance from the origin where that is larger (far from the
/// origin the coordinates themselves carry the rounding), as for polygons.
fn tolerance(points: &[Vec3]) -> f32 {
    let (lo, hi) = points.iter().fold((points[0], points[0]), |(lo, hi), &p| {
        (lo.min(p), hi.max(p))
    });
    let extent = (hi - lo)
        .max_element()
        .max(lo.abs().max(hi.abs()).max_element() * 0.1);
    HULL_RELATIVE_TOLERANCE * extent
}

fn extreme_pair(points: &[Vec3]) -> (usize, usize) {
    let mut best = (0, 0, -1.0_f32);
    for axis in 0..3 {
        let (lo, _) = farthest(points, |p| -p[axis]);
        let (hi, _) = farthest(points, |p| p[axis]);
        let spread = points[hi][axis] - points[lo][axis];
        if spread > best.2 {
            best = (lo, hi, spread);
        }
    }
    (best.0, best.1)
}

/// The index of the point with the largest `key`, and that key (the first on ties).
fn farthest(points: &[Vec3], key: impl Fn(Vec3) -> f32) -> (usize, f32) {
    let mut best = (0, key(points[0]));
    for (i, &p) in points.iter().enumerate().skip(1) {
        let k = key(p);
        if k > best.1 {
            best = (i, k);
        }
    }
    best
}

/// Volume (m³), centroid and second moment (`∫ x xᵀ dV` about the centroid) of the convex
/// solid bounded by `triangles`, rounded by `radius` (every point within `radius` of it).
///
/// The core by a fan of tetrahedra from an interior point: for a tetrahedron with one vertex
/// at the origin and the others `a`, `b`, `c`, the volume is `det / 6` and `∫ x xᵀ dV = det /
/// 120 (a aᵀ + b bᵀ + c cᵀ + s sᵀ)`, `s = a + b + c` (Tonon, "Explicit exact formulas for the
/// 3-D tetrahedron inertia tensor", 2004).
///
/// The rounding, exactly, as the Minkowski sum of the core and a ball splits into pieces that
/// meet only on their boundaries (the pieces behind Steiner's formula): over each face `F`
/// (unit normal `n`) a slab `y + t n`, `t ≤ r`; over each edge (length `ℓ`, between faces
/// whose normals make the angle `α`) a wedge of a cylinder, `c(s) + ρ u(φ)`; at each corner
/// `v` a cone of the ball over its normal cone `Ω_v`, `v + ρ u`. Integrating the polynomial
/// `x xᵀ` over each in its own coordinates gives powers of `r` times integrals of `u` and
/// `u uᵀ` over an arc (`φ` across `α`) or over `Ω_v`. Over `Ω_v`, a spherical polygon whose
/// arcs lie on the planes `u · e = 0` of the corner's edges `e` (unit, pointing away from the
/// corner, which is each arc's outward normal), the integrands are spherical harmonics of
/// degree 1 and 2 plus a constant, and Green's formula on the sphere (`Δ Y = -l (l + 1) Y`)
/// turns them into sums over the arcs: `∫ u = -½ Σ α e` and `∫ u uᵀ = Ω/3 I - ⅙ Σ (e gᵀ + g
/// eᵀ)` with `g = ∫ u` along the arc `= tan(α/2) (n₁ + n₂)`; `Ω_v` itself is the corner's
/// angle deficit (`2π` less the faces' angles there). Computed in `f64` about the corners'
/// mean, so that a hull far from its frame's origin keeps its precision.
pub(crate) fn solid_moments(
    corners: &[Vec3],
    triangles: &[[usize; 3]],
    radius: f32,
) -> (f32, Vec3, Mat3) {
    let mean = corners.iter().fold(DVec3::ZERO, |s, p| s + p.as_dvec3()) / corners.len() as f64;
    let p: Vec<DVec3> = corners.iter().map(|c| c.as_dvec3() - mean).collect();
    let r = f64::from(radius);
    let (r2, r3, r4, r5) = (r * r, r * r * r, r * r * r * r, r * r * r * r * r);
    let outer = |a: DVec3, b: DVec3| DMat3::from_cols(a * b.x, a * b.y, a * b.z);
    let sym = |a: DVec3, b: DVec3| outer(a, b) + outer(b, a);
    let mut volume = 0.0;
    let mut first = DVec3::ZERO;
    let mut second = DMat3::ZERO;
    let unit_normal = |t: &[usize; 3]| {
        let [a, b, c] = t.map(|i| p[i]);
        (b - a).cross(c - a).normalize_or_zero()
    };
    // Per corner: the angle deficit, `∫ u` and `Σ (e gᵀ + g eᵀ)` over its normal cone.
    let mut deficit = vec![2.0 * core::f64::consts::PI; p.len()];
    let mut cone_first = vec![DVec3::ZERO; p.len()];
    let mut cone_arcs = vec![DMat3::ZERO; p.len()];
    for (k, t) in triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| p[i]);
        let s = a + b + c;
        let squares = outer(a, a) + outer(b, b) + outer(c, c) + outer(s, s);
        let det = a.dot(b.cross(c));
        volume += det / 6.0;
        first += s * (det / 24.0);
        second += squares * (det / 120.0);
        if r == 0.0 {
            continue;
        }
        // The slab over the face: ∫ over the triangle of y is A s / 3, of y yᵀ A / 12 (squares).
        let n = unit_normal(t);
        let area = 0.5 * (b - a).cross(c - a).length();
        let f = s * (area / 3.0);
        volume += r * area;
        first += f * r + n * (r2 / 2.0 * area);
        second +=
            squares * (r * area / 12.0) + sym(f, n) * (r2 / 2.0) + outer(n, n) * (r3 / 3.0 * area);
        for e in 0..3 {
            let (u, w, x) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
            let (pu, pw, px) = (p[u], p[w], p[x]);
            let (to_w, to_x) = (pw - pu, px - pu);
            deficit[u] -= to_w.cross(to_x).length().atan2(to_w.dot(to_x));
            // Each edge is met twice (once each way): count it from the face with u < w.
            let Some(other) = triangles
                .iter()
                .enumerate()
                .find(|(j, o)| *j != k && (0..3).any(|f| o[f] == w && o[(f + 1) % 3] == u))
                .map(|(_, o)| o)
            else {
                continue;
            };
            if u > w {
                continue;
            }
            let m = unit_normal(other);
            let alpha = n.cross(m).length().atan2(n.dot(m));
            let length = to_w.length();
            if alpha == 0.0 || length == 0.0 {
                continue;
            }
            let edge = to_w / length;
            // The wedge: its axis c(s) from pu to pw, its directions u(φ) from n to m.
            let g = (n + m) * (alpha / 2.0).tan();
            let mid = (n + m).normalize();
            let side = edge.cross(mid);
            let arc_squares = outer(mid, mid) * ((alpha + alpha.sin()) / 2.0)
                + outer(side, side) * ((alpha - alpha.sin()) / 2.0);
            let axis_first = (pu + pw) * (length / 2.0);
            let axis_second =
                (outer(pu, pu) + outer(pw, pw)) * (length / 3.0) + sym(pu, pw) * (length / 6.0);
            volume += r2 / 2.0 * alpha * length;
            first += axis_first * (r2 / 2.0 * alpha) + g * (r3 / 3.0 * length);
            second += axis_second * (r2 / 2.0 * alpha)
                + sym(axis_first, g) * (r3 / 3.0)
                + arc_squares * (r4 / 4.0 * length);
            // The same arc bounds both ends' normal cones, its outward normal the edge's
            // direction away from each end.
            for (corner, out) in [(u, edge), (w, -edge)] {
                cone_first[corner] -= out * (alpha / 2.0);
                cone_arcs[corner] += sym(out, g);
            }
        }
    }
    if r > 0.0 {
        for (i, &v) in p.iter().enumerate() {
            let omega = deficit[i];
            let u1 = cone_first[i];
            let u2 = DMat3::IDENTITY * (omega / 3.0) - cone_arcs[i] * (1.0 / 6.0);
            volume += r3 / 3.0 * omega;
            first += v * (r3 / 3.0 * omega) + u1 * (r4 / 4.0);
            second += outer(v, v) * (r3 / 3.0 * omega) + sym(v, u1) * (r4 / 4.0) + u2 * (r5 / 5.0);
        }
    }
    let centroid = first / volume;
    // About the centroid: ∫ x xᵀ dV - V c cᵀ.
    second -= outer(centroid, centroid) * volume;
    (
        (volume) as f32,
        (mean + centroid).as_vec3(),
        second.as_mat3(),
    )
}

/// The rotational inertia of a solid whose second moment about its centre of mass is
/// `second` (`∫ x xᵀ dV`), at `density`: `ρ (tr(C) I - C)`.
pub(crate) fn inertia_from_second_moment(second: Mat3, density: f32) -> Mat3 {
    let trace = second.x_axis.x + second.y_axis.y + second.z_axis.z;
    (Mat3::from_diagonal(Vec3::splat(trace)) - second) * density
}
