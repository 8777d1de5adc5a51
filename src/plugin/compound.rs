//! Compound bodies: the colliders on a body's descendants (reached through entities that are
//! neither bodies nor targets) belong to it and move with it rigidly. Which body each one
//! belongs to is kept as the hierarchy changes ([`PartOf`](super::PartOf), by the observers of
//! [`parts`](super::parts)); [`update_compounds`] places each body's parts every step into
//! [`Compounds`], with the combined mass properties and reach the solve and the broad phase
//! need; a body without parts is not listed there and costs nothing new.
//!
//! A part's shape is placed in the body frame by the `Transform`s between the body and the
//! part ([`pose_in`]), scaled by the product of their scales and the body's uniform world
//! scale, as a body's own collider is: offsets, shapes and mass are those of the body as drawn
//! (the body frame the solver sweeps is rigid).

use bevy_ecs::prelude::*;
use bevy_transform::components::Transform;
use glam::Vec2;

use super::gather::BodyShape;
use super::hierarchy::{Ancestry, Planar, body_scale, pose_in};
use super::outcome::CcdError;
use super::parts::BodyParts;
#[cfg(any(test, feature = "testing"))]
use super::parts::{Kind, owner_of};
use super::workspace::{BodyEntry, COMPOUND, CcdWorkspace};
use super::{Collider, CollisionLayers, StaticCollider, StepPoses, usable_mass};
use crate::geometry::{BodyPart, MassProperties, Pose, ShapeProxy};

/// The parts of one compound body: `Compounds::parts[start..start + count]`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CompoundBody {
    pub(crate) body: Entity,
    start: u32,
    count: u32,
    /// The combined mass properties at unit density, in the body frame.
    pub(crate) mass: MassProperties,
    /// The farthest any point of a part is from the combined centre of mass (m).
    reach: f32,
    /// The union of the parts' layers: the broad phase keeps a target any part may hit.
    pub(crate) layers: CollisionLayers,
    /// A part whose pose could not be read: the body is not swept.
    pub(crate) error: Option<CcdError>,
}

impl CompoundBody {
    /// What the listing reads of the body's shape: the combined centre of mass and reach.
    pub(crate) fn shape(&self) -> BodyShape {
        BodyShape {
            local_center: self.mass.center,
            reach: self.reach,
            mass_ok: usable_mass(self.mass.mass, self.mass.inertia),
        }
    }
}

/// Every compound body of the step, by entity, and their parts (flat lists, one index per
/// part). Rebuilt each step by [`update_compounds`]; empty when no body has child colliders.
#[derive(Resource, Default)]
pub(crate) struct Compounds {
    bodies: Vec<CompoundBody>,
    shapes: Vec<BodyPart>,
    entities: Vec<Entity>,
    layers: Vec<CollisionLayers>,
    /// The parts found this step, before they are grouped by body (kept to reuse its memory).
    found: Vec<Found>,
}

/// `pose`, a part's pose in the frame of a body of uniform world scale `s`, in the rigid body
/// frame the solver sweeps: its offset and scale times `s` (a scale that cannot be swept
/// leaves it as it is; the body is refused for it).
fn at_scale(pose: Planar, s: f32) -> Planar {
    if s == 1.0 || !(s.is_finite() && s > 0.0) {
        return pose;
    }
    Planar {
        position: s * pose.position,
        angle: pose.angle,
        scale: s * pose.scale,
    }
}

/// A part found by [`update_compounds`]: its body, its entity, and its shape and unit mass in
/// the body frame or the error of reading its pose.
type Found = (Entity, Entity, Result<(BodyPart, MassProperties), CcdError>);

impl Compounds {
    /// Whether no body has child colliders.
    pub(crate) fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    /// The compound body `entity`, if it is one.
    pub(crate) fn find(&self, entity: Entity) -> Option<&CompoundBody> {
        let at = self.bodies.binary_search_by_key(&entity, |b| b.body).ok()?;
        self.bodies.get(at)
    }

    /// The parts' shapes and layers of `body`.
    pub(crate) fn parts(&self, body: &CompoundBody) -> (&[BodyPart], &[CollisionLayers]) {
        let range = body.start as usize..(body.start + body.count) as usize;
        (&self.shapes[range.clone()], &self.layers[range])
    }

    /// The mass properties at unit density of the swept body `entry`, about its centre of
    /// mass; unless it is compound, also its one part, its own [`Collider`] at the body's
    /// world scale, into `own`.
    #[inline]
    pub(crate) fn read(
        &self,
        entry: &BodyEntry,
        colliders: &Query<&Collider, Without<StaticCollider>>,
        own: &mut BodyPart,
    ) -> Result<MassProperties, CcdError> {
        if entry.flags & COMPOUND != 0 {
            let body = self.find(entry.entity).ok_or(CcdError::InvalidBodyData)?;
            return Ok(body.mass);
        }
        let collider = colliders
            .get(entry.entity)
            .map_err(|_| CcdError::InvalidBodyData)?;
        // Scaled by the body's uniform world scale (1 leaves every bit as it is). The proxy is
        // copied into `own` in place: through a returned pair it was copied twice.
        let mut mass = collider.mass_properties(1.0);
        (mass.mass, mass.inertia) = collider.scaled_unit_mass(entry.scale);
        own.proxy = *collider.proxy();
        own.core_radius = collider.core_radius();
        if entry.scale != 1.0 {
            (own.proxy, own.core_radius) = collider.scaled(entry.scale);
        }
        own.core_center = mass.center * entry.scale;
        Ok(mass)
    }

    /// The parts of the swept body `entry` and their layers: `own`, its own collider's part
    /// ([`Self::read`]), with the body's layers (`None`) unless it is compound.
    #[inline]
    pub(crate) fn parts_of<'a>(
        &'a self,
        entry: &BodyEntry,
        own: &'a BodyPart,
    ) -> (&'a [BodyPart], Option<&'a [CollisionLayers]>) {
        if entry.flags & COMPOUND != 0
            && let Some(body) = self.find(entry.entity)
        {
            let (parts, layers) = self.parts(body);
            return (parts, Some(layers));
        }
        (core::slice::from_ref(own), None)
    }

    /// The collider entity of part `part` of the swept body `entry`: the body itself unless it
    /// is compound.
    pub(crate) fn collider(&self, entry: &BodyEntry, part: u32) -> Entity {
        if entry.flags & COMPOUND == 0 {
            return entry.entity;
        }
        self.find(entry.entity)
            .and_then(|b| self.entities.get((b.start + part) as usize))
            .copied()
            .unwrap_or(entry.entity)
    }
}

/// A collider's shape and unit mass placed by `pose` (a similarity) into the body frame:
/// points and radius times the scale `s`, the mass times `s²`, the inertia times `s⁴`.
fn placed(collider: &Collider, pose: Planar) -> (BodyPart, MassProperties) {
    let s = pose.scale;
    let frame = Pose::new(pose.position, pose.angle);
    let proxy = collider.proxy();
    let mut points = [Vec2::ZERO; crate::geometry::MAX_POLYGON_VERTICES];
    for (to, from) in points.iter_mut().zip(proxy.points()) {
        *to = frame.transform_point(s * *from);
    }
    let unit = collider.mass_properties(1.0);
    let center = frame.transform_point(s * unit.center);
    let part = BodyPart {
        proxy: ShapeProxy::from_parts(&points[..proxy.count()], s * proxy.radius),
        core_center: center,
        core_radius: s * collider.core_radius(),
    };
    let mass = MassProperties {
        mass: unit.mass * s * s,
        center,
        inertia: unit.inertia * (s * s) * (s * s),
    };
    (part, mass)
}

/// The mass properties of rigidly joined parts (all in one frame), by the parallel-axis
/// theorem: `m = Σ m_i`, `c = Σ m_i c_i / m`, `I = Σ (I_i + m_i |c_i - c|²)`.
pub(crate) fn combined_mass(parts: impl Iterator<Item = MassProperties> + Clone) -> MassProperties {
    let mass: f32 = parts.clone().map(|p| p.mass).sum();
    let center = parts.clone().map(|p| p.mass * p.center).sum::<Vec2>() / mass;
    let inertia = parts
        .map(|p| p.inertia + p.mass * p.center.distance_squared(center))
        .sum();
    MassProperties {
        mass,
        center,
        inertia,
    }
}

/// A body's uniform world scale: its own ([`body_scale`]), times its parent's for a child body
/// (`child_frames` of the step, by entity; a chain with no world pose has its error from the
/// record passes, whatever this is).
#[inline]
fn world_scale(
    entity: Entity,
    transform: &Transform,
    child_frames: &[(Entity, Result<Planar, CcdError>)],
) -> f32 {
    let mut scale = body_scale(transform);
    if !child_frames.is_empty()
        && let Ok(at) = child_frames.binary_search_by_key(&entity, |(e, _)| *e)
        && let Ok(frame) = child_frames[at].1
    {
        scale *= frame.scale;
    }
    scale
}

/// The bodies' query: their parts, own collider, poses and `Transform` (for their world
/// scale).
type BodyQuery<'w, 's> = Query<
    'w,
    's,
    (
        Option<&'static BodyParts>,
        Option<&'static Collider>,
        &'static Transform,
    ),
    (With<StepPoses>, Without<StaticCollider>),
>;

/// Part of [`CcdStepSystems::RecordEnd`](super::CcdStepSystems::RecordEnd): lists every
/// compound body (one with [`BodyParts`]) and its parts (its own [`Collider`], if any, first;
/// then its child colliders in entity order), with the combined mass properties and reach. A child collider's [`CollisionLayers`] are its own, else the
/// body's. Every part, the body's own collider too, is placed at the body's uniform world scale
/// ([`at_scale`]).
///
/// Which body a collider belongs to is kept by the observers of [`parts`](super::parts) as
/// the hierarchy changes; the parts' shapes are placed again each step, so that a part moved
/// or reshaped between steps counts from the next step. The work is in proportion to the
/// parts, none without any.
pub(crate) fn update_compounds(
    mut compounds: ResMut<Compounds>,
    owners: Query<Entity, (With<BodyParts>, Without<StaticCollider>)>,
    part_colliders: Query<&Collider>,
    ancestry: Ancestry,
    layers: Query<&CollisionLayers>,
    workspace: Res<CcdWorkspace>,
    bodies: BodyQuery,
) {
    let compounds = compounds.as_mut();
    if owners.is_empty() && compounds.bodies.is_empty() {
        return;
    }
    let Compounds {
        bodies: list,
        shapes,
        entities,
        layers: part_layers,
        found,
    } = compounds;
    list.clear();
    shapes.clear();
    entities.clear();
    part_layers.clear();
    found.clear();
    let frames = &workspace.bodies.child_frames;
    for body in &owners {
        let Ok((Some(parts), _, transform)) = bodies.get(body) else {
            continue;
        };
        let s = world_scale(body, transform, frames);
        for part in parts.iter() {
            let Ok(collider) = part_colliders.get(part) else {
                continue;
            };
            let placed = pose_in(part, Some(body), &ancestry)
                .map(|pose| placed(collider, at_scale(pose, s)));
            found.push((body, part, placed));
        }
    }
    found.sort_unstable_by_key(|&(body, part, _)| (body, part));
    let mut rest = &found[..];
    while let Some(&(body, ..)) = rest.first() {
        let count = rest.iter().take_while(|f| f.0 == body).count();
        let (group, later) = rest.split_at(count);
        rest = later;
        let Ok((_, own, transform)) = bodies.get(body) else {
            continue;
        };
        let s = world_scale(body, transform, frames);
        let body_layers = layers.get(body).copied().unwrap_or_default();
        let start = shapes.len();
        let mut masses = smallvec::SmallVec::<[MassProperties; 8]>::new();
        if let Some(collider) = own {
            let (part, mass) = placed(collider, at_scale(Planar::IDENTITY, s));
            shapes.push(part);
            entities.push(body);
            part_layers.push(body_layers);
            masses.push(mass);
        }
        let mut error = None;
        for &(_, part, ref placed) in group {
            match placed {
                Ok((shape, mass)) => {
                    shapes.push(*shape);
                    entities.push(part);
                    part_layers.push(layers.get(part).copied().unwrap_or(body_layers));
                    masses.push(*mass);
                }
                Err(e) => error = error.or(Some(*e)),
            }
        }
        let mass = combined_mass(masses.iter().copied());
        let union = part_layers[start..]
            .iter()
            .fold(CollisionLayers::new(0, 0), |u, l| {
                CollisionLayers::new(u.memberships | l.memberships, u.filters | l.filters)
            });
        let reach = shapes[start..]
            .iter()
            .map(|p| p.proxy.reach(mass.center))
            .fold(0.0, f32::max);
        list.push(CompoundBody {
            body,
            start: start as u32,
            count: (shapes.len() - start) as u32,
            mass,
            reach,
            layers: union,
            error: error.or((shapes.len() == start).then_some(CcdError::InvalidBodyData)),
        });
    }
}

/// Every collider of every CCD body, read from the hierarchy as it is now (not from the
/// plugin's lists): (body, collider entity, the body's pose, the collider's shape in the body
/// frame, its layers). For the containment checks of [`testing`](super::testing).
#[cfg(any(test, feature = "testing"))]
pub(crate) fn body_colliders(
    world: &mut World,
) -> Vec<(Entity, Entity, Pose, ShapeProxy, CollisionLayers)> {
    use super::CcdEnabled;
    use bevy_ecs::system::RunSystemOnce;
    use bevy_transform::components::Transform;
    type Own<'w, 's> = Query<
        'w,
        's,
        (Entity, &'static Collider, &'static Transform),
        (With<CcdEnabled>, Without<StaticCollider>),
    >;
    /// Each entity's kind ([`owner_of`]).
    type Kinds<'w, 's> = Query<
        'w,
        's,
        (
            Has<CcdEnabled>,
            Has<StaticCollider>,
            Has<Collider>,
            Option<&'static ChildOf>,
        ),
    >;
    let read = |own: Own,
                parts: Query<(Entity, &Collider), With<ChildOf>>,
                kinds: Kinds,
                ancestry: Ancestry,
                transforms: Query<&Transform>,
                layers: Query<&CollisionLayers>| {
        let pose = |transform: &Transform| {
            let (p, angle) = super::components::planar_pose(transform);
            Pose::new(p, angle)
        };
        let layers_of = |e: Entity| layers.get(e).copied().ok();
        let mut out: Vec<_> = own
            .iter()
            .map(|(body, collider, transform)| {
                let layers = layers_of(body).unwrap_or_default();
                // Scaled as the plugin sweeps it (a `Transform` it refuses, as it is).
                let scale = super::hierarchy::body_scale(transform);
                let (proxy, _) = collider.scaled(if scale > 0.0 { scale } else { 1.0 });
                (body, body, pose(transform), proxy, layers)
            })
            .collect();
        for (part, collider) in &parts {
            let kind_of = |e| {
                let (body, target, collider, parent) = kinds.get(e).ok()?;
                let parent = parent.map(ChildOf::parent);
                Some(Kind {
                    body,
                    target,
                    collider,
                    parent,
                })
            };
            let Some(body) = owner_of(part, kind_of) else {
                continue;
            };
            let (Ok(local), Ok(transform)) =
                (pose_in(part, Some(body), &ancestry), transforms.get(body))
            else {
                continue;
            };
            let layers = layers_of(part).or(layers_of(body)).unwrap_or_default();
            let s = super::hierarchy::body_scale(transform);
            let shape = placed(collider, at_scale(local, s)).0.proxy;
            out.push((body, part, pose(transform), shape, layers));
        }
        out.sort_by_key(|item| (item.0, item.1));
        out
    };
    world.run_system_once(read).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Circle, Polygon, Shape};

    /// Two discs of radius `r` at `(±d, 0)`: `m = 2 π r²`, centre 0, and by the parallel-axis
    /// theorem `I = 2 (π r² · r² / 2 + π r² d²)`.
    #[test]
    fn two_discs_combine_by_the_parallel_axis_theorem() {
        let (r, d) = (0.3f32, 1.25f32);
        let disc = Collider::new(Shape::from(Circle::new(r).unwrap()));
        let at = |x: f32| Planar {
            position: Vec2::new(x, 0.0),
            angle: 0.4,
            scale: 1.0,
        };
        let both = [placed(&disc, at(-d)).1, placed(&disc, at(d)).1];
        let m = combined_mass(both.iter().copied());
        let pi = core::f32::consts::PI;
        let (mass, inertia) = (
            2.0 * pi * r * r,
            2.0 * (pi * r * r * r * r / 2.0 + pi * r * r * d * d),
        );
        // A few f32 roundings of values near 1: relative 1e-6.
        assert!((m.mass - mass).abs() <= 1e-6 * mass, "{m:?}");
        assert!(m.center.length() <= 1e-6, "{m:?}");
        assert!(
            (m.inertia - inertia).abs() <= 1e-6 * inertia,
            "{m:?} vs {inertia}"
        );
    }

    /// A box `2a × 2b` placed at scale `s`, off centre, beside a disc: against the analytic
    /// values of the scaled box (`m = 4 a b s²`, `I = m s² (a² + b²) / 3`) and the disc.
    #[test]
    fn a_scaled_box_and_a_disc_combine_by_the_parallel_axis_theorem() {
        let (a, b, s, r) = (0.5f32, 0.2f32, 2.0f32, 0.1f32);
        let bar = Collider::new(Shape::from(Polygon::rectangle(a, b).unwrap()));
        let disc = Collider::new(Shape::from(Circle::new(r).unwrap()));
        let box_at = Vec2::new(0.0, 3.0);
        let parts = [
            placed(
                &bar,
                Planar {
                    position: box_at,
                    angle: 0.0,
                    scale: s,
                },
            )
            .1,
            placed(&disc, Planar::IDENTITY).1,
        ];
        let m = combined_mass(parts.iter().copied());
        let pi = core::f32::consts::PI;
        let m_box = 4.0 * a * b * s * s;
        let i_box = m_box * s * s * (a * a + b * b) / 3.0;
        let m_disc = pi * r * r;
        let i_disc = m_disc * r * r / 2.0;
        let mass = m_box + m_disc;
        let center = box_at * m_box / mass;
        let inertia = i_box
            + m_box * (box_at - center).length_squared()
            + i_disc
            + m_disc * center.length_squared();
        // A few f32 roundings of values near 1: relative 1e-6 (the inertia sums terms of
        // one sign, so its rounding stays relative too).
        assert!((m.mass - mass).abs() <= 1e-6 * mass, "{m:?}");
        assert!(
            (m.center - center).length() <= 1e-6 * center.length(),
            "{m:?}"
        );
        assert!(
            (m.inertia - inertia).abs() <= 2e-6 * inertia,
            "{m:?} vs {inertia}"
        );
    }
}
