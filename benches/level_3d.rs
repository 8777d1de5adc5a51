//! A seeded level in space for the 3D tree and cast benches: one static per 4 m cell of a
//! grid ten storeys high, as the plane's scene level has one per 4 m square. 30 % walls
//! (0.1-0.6 m thick, 1-12 m by 1-6 m, turned about the vertical), 40 % boxes (0.4-2.4 m, any
//! rotation, a fifth of them rounded), 15 % balls, 10 % capsules and 5 % hulls of eight
//! points; the same seed gives the same level.

use bevy_ccd::geometry::d3::{Aabb, Capsule, ConvexHull, Cuboid, Pose, Shape, Sphere, StaticItem};
use bevy_ccd_fixtures::SceneRng;
use glam::{Quat, Vec3};

/// A cell's side (m).
const CELL: f32 = 4.0;
/// Storeys of cells.
const STOREYS: usize = 10;

/// The statics and the box of the grid they fill.
pub struct Level3d {
    pub items: Vec<StaticItem>,
    pub interior: Aabb,
}

/// A direction drawn uniformly over the sphere.
pub fn unit(rng: &mut SceneRng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let len = v.length();
        if (0.1..=1.0).contains(&len) {
            return v / len;
        }
    }
}

/// A point of `bounds` drawn uniformly.
pub fn point_in(bounds: &Aabb, rng: &mut SceneRng) -> Vec3 {
    Vec3::new(
        rng.range(bounds.min.x, bounds.max.x),
        rng.range(bounds.min.y, bounds.max.y),
        rng.range(bounds.min.z, bounds.max.z),
    )
}

/// `n` statics, seeded.
pub fn level_3d(n: usize, seed: u64) -> Level3d {
    let mut rng = SceneRng::new(seed);
    let columns = (n as f32 / STOREYS as f32).sqrt().ceil() as usize;
    let items = (0..n)
        .map(|i| {
            let cell = Vec3::new(
                (i % columns) as f32,
                ((i / columns) % STOREYS) as f32,
                (i / (columns * STOREYS)) as f32,
            );
            let at = (cell + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())) * CELL;
            let turn = Quat::from_scaled_axis(unit(&mut rng) * rng.range(0.0, 3.1));
            let kind = rng.next_f32();
            let (shape, rotation) = if kind < 0.3 {
                let half = Vec3::new(
                    rng.range(0.5, 6.0),
                    rng.range(0.5, 3.0),
                    rng.range(0.05, 0.3),
                );
                let yaw = Quat::from_rotation_y(rng.range(0.0, std::f32::consts::TAU));
                (Shape::from(Cuboid::new(half, 0.0).unwrap()), yaw)
            } else if kind < 0.7 {
                let half = Vec3::new(
                    rng.range(0.2, 1.2),
                    rng.range(0.2, 1.2),
                    rng.range(0.2, 1.2),
                );
                let radius = if rng.next_f32() < 0.2 {
                    rng.range(0.02, 0.2)
                } else {
                    0.0
                };
                (Shape::from(Cuboid::new(half, radius).unwrap()), turn)
            } else if kind < 0.85 {
                let radius = rng.range(0.2, 1.2);
                (Shape::from(Sphere::new(radius).unwrap()), Quat::IDENTITY)
            } else if kind < 0.95 {
                let half = unit(&mut rng) * rng.range(0.2, 1.5);
                let radius = rng.range(0.1, 0.6);
                (
                    Shape::from(Capsule::new(-half, half, radius).unwrap()),
                    turn,
                )
            } else {
                let points: Vec<Vec3> = (0..8)
                    .map(|_| unit(&mut rng) * rng.range(0.4, 1.2))
                    .collect();
                (Shape::from(ConvexHull::new(&points, 0.0).unwrap()), turn)
            };
            StaticItem::new(shape, Pose::new(at, rotation))
        })
        .collect();
    let rows = n.div_ceil(columns * STOREYS);
    let interior = Aabb {
        min: Vec3::ZERO,
        max: Vec3::new(columns as f32, STOREYS as f32, rows as f32) * CELL,
    };
    Level3d { items, interior }
}
