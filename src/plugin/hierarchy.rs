//! World poses through the `ChildOf` hierarchy, composed from the `Transform`s at the time the
//! step runs: `GlobalTransform` is propagated in `PostUpdate`, so in the fixed schedules it
//! still holds the last frame's poses.
//!
//! A `Transform` the plugin can read is a *planar similarity*: a translation in the plane, a
//! rotation about z and a uniform scale. Its z translation and z scale are ignored (the
//! world is the xy plane); anything else is [`CcdError::UnsupportedTransform`], but for a
//! body's own rotation, which may also be a mirror ([`body_scale`]).

use bevy_ecs::change_detection::Tick;
use bevy_ecs::prelude::*;
use bevy_transform::components::Transform;
use glam::{Vec2, Vec3};

use super::CcdError;

/// The most ancestors the plugin follows from an entity to its root; a longer chain is taken
/// for a cycle ([`CcdError::InvalidHierarchy`]).
pub const MAX_HIERARCHY_DEPTH: usize = 64;

/// Largest tilt out of the plane a rotation may have, as `|(q.x, q.y)|` of its unit
/// quaternion: `sin(tilt / 2)`, so about 0.11°. The plane's projection of a shape tilted by
/// `t` is shorter by `1 - cos t`, under 2e-6 of its size here: far below any slop.
const MAX_TILT: f32 = 1e-3;

/// Largest relative difference between a scale's x and y for it to count as uniform: a few
/// roundings of a scale composed or typed in decimal.
const SCALE_TOLERANCE: f32 = 1e-5;

/// A planar similarity: scale by `scale`, rotate by `angle` about z, translate by
/// `position`, in that order (a `Transform`'s order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Planar {
    /// Translation (m).
    pub(crate) position: Vec2,
    /// Rotation about z (rad).
    pub(crate) angle: f32,
    /// Uniform scale, positive.
    pub(crate) scale: f32,
}

impl Planar {
    /// The identity.
    pub(crate) const IDENTITY: Self = Self {
        position: Vec2::ZERO,
        angle: 0.0,
        scale: 1.0,
    };

    /// The similarity of `transform`, or why it is not one.
    pub(crate) fn of(transform: &Transform) -> Result<Self, CcdError> {
        let q = transform.rotation;
        let s = transform.scale;
        let position = transform.translation.truncate();
        if !position.is_finite() || !q.is_finite() || !s.is_finite() {
            return Err(CcdError::NonFiniteTransform);
        }
        let length = q.length();
        let uniform = (s.x - s.y).abs() <= SCALE_TOLERANCE * s.x.abs().max(s.y.abs());
        let in_plane = Vec2::new(q.x, q.y).length() <= MAX_TILT * length;
        if !uniform || s.x < f32::MIN_POSITIVE || !in_plane || length < f32::MIN_POSITIVE {
            return Err(CcdError::UnsupportedTransform);
        }
        Ok(Self {
            position,
            angle: super::components::planar_pose(transform).1,
            scale: s.x,
        })
    }

    /// `self` after `inner`: the pose in `self`'s parent frame of what `inner` places in
    /// `self`'s frame. `p = self.p + self.s R(self.a) inner.p`, angles add, scales multiply.
    pub(crate) fn compose(self, inner: Self) -> Self {
        let (sin, cos) = self.angle.sin_cos();
        let p = inner.position;
        Self {
            position: self.position
                + self.scale * Vec2::new(cos * p.x - sin * p.y, sin * p.x + cos * p.y),
            angle: self.angle + inner.angle,
            scale: self.scale * inner.scale,
        }
    }

    /// The `inner` with `self.compose(inner) == outer`: the local pose, in `self`'s frame,
    /// that gives the world pose `outer` (a resolved body written back under its parent).
    pub(crate) fn local_of(self, outer: Self) -> Self {
        let (sin, cos) = self.angle.sin_cos();
        let d = (outer.position - self.position) / self.scale;
        Self {
            position: Vec2::new(cos * d.x + sin * d.y, -sin * d.x + cos * d.y),
            angle: outer.angle - self.angle,
            scale: outer.scale / self.scale,
        }
    }
}

/// What walking up the hierarchy reads: each entity's `Transform` and parent.
pub(crate) type Ancestry<'w, 's> =
    Query<'w, 's, (Option<&'static Transform>, Option<&'static ChildOf>)>;

/// The same, with change ticks: whether a chain moved since the last step.
pub(crate) type TickedAncestry<'w, 's> = Query<
    'w,
    's,
    (
        Option<Ref<'static, Transform>>,
        Option<Ref<'static, ChildOf>>,
    ),
>;

/// The pose of `entity` in the frame of its ancestor `frame` (the world when `None` or when
/// `frame` is not an ancestor): its own `Transform` composed with those of its ancestors below
/// `frame`.
pub(crate) fn pose_in(
    entity: Entity,
    frame: Option<Entity>,
    ancestry: &Ancestry,
) -> Result<Planar, CcdError> {
    pose_with(entity, frame, |at| ancestry.get(at).ok())
}

/// [`pose_in`] with the `Transform` and parent of each entity read by `link` (`None` for an
/// entity that is not there): a query in the systems, the world in a component hook.
pub(crate) fn pose_with<'a>(
    entity: Entity,
    frame: Option<Entity>,
    link: impl Fn(Entity) -> Option<(Option<&'a Transform>, Option<&'a ChildOf>)>,
) -> Result<Planar, CcdError> {
    let mut pose = Planar::IDENTITY;
    let mut at = entity;
    for _ in 0..=MAX_HIERARCHY_DEPTH {
        let Some((Some(transform), parent)) = link(at) else {
            return Err(CcdError::InvalidHierarchy);
        };
        pose = Planar::of(transform)?.compose(pose);
        match parent.map(ChildOf::parent) {
            Some(up) if Some(up) == frame => return Ok(pose),
            Some(up) => at = up,
            None => return Ok(pose),
        }
    }
    Err(CcdError::InvalidHierarchy)
}

/// The world pose of a CCD body with the `Transform` `own` under `parent`, and its parent's
/// world pose, which the write-back turns a resolved world pose back into a local one with.
/// The world scale (the parent's times the body's own, [`body_scale`]) scales its collider.
pub(crate) fn body_pose<'a>(
    own: &Transform,
    parent: Entity,
    link: impl Fn(Entity) -> Option<(Option<&'a Transform>, Option<&'a ChildOf>)>,
) -> Result<(Planar, Planar), CcdError> {
    let frame = pose_with(parent, None, link)?;
    let Some((position, angle)) = super::components::pose_of(own) else {
        return Err(CcdError::NonFiniteTransform);
    };
    let scale = body_scale(own);
    if scale.is_nan() {
        return Err(CcdError::NonFiniteTransform);
    } else if scale == 0.0 {
        return Err(CcdError::UnsupportedTransform);
    }
    let local = Planar {
        position,
        angle,
        scale,
    };
    Ok((frame.compose(local), frame))
}

/// A body's own uniform scale, from the parts of its `Transform` its pose does not read: NaN
/// when the translation's z or the scale is not finite; 0 when the `Transform` does not keep
/// the plane (a scale not uniform in x and y or not positive, a rotation tilted out of the
/// plane by more than [`MAX_TILT`] that is not a mirror either, a zero rotation); else the
/// scale. A *mirror* is a half turn about an axis in the plane (a sprite flipped by a half
/// turn about y): `|(q.z, q.w)|` within [`MAX_TILT`] of zero.
///
/// The plugin changes only the translation's x and y and the rotation about z of a body's
/// `Transform`: the rest is the user's, kept bit for bit, but must still describe a body in
/// the plane. A tilt other than a mirror would need the collider projected onto the plane.
#[inline]
pub(crate) fn body_scale(transform: &Transform) -> f32 {
    let (q, s) = (transform.rotation, transform.scale);
    // Most bodies of a 2D game: unit scale and a turn about z alone, which the general test
    // below passes too (the tilt is 0; the length is that of `(q.z, q.w)`).
    if s == Vec3::ONE
        && q.x == 0.0
        && q.y == 0.0
        && q.z * q.z + q.w * q.w >= f32::MIN_POSITIVE
        && transform.translation.z.is_finite()
    {
        return 1.0;
    }
    if !(transform.translation.z.is_finite() && s.is_finite()) {
        return f32::NAN;
    }
    let uniform = (s.x - s.y).abs() <= SCALE_TOLERANCE * s.x.abs().max(s.y.abs());
    let length = q.length_squared();
    let limit = MAX_TILT * MAX_TILT * length;
    let in_plane = q.x * q.x + q.y * q.y <= limit || q.z * q.z + q.w * q.w <= limit;
    if uniform && s.x >= f32::MIN_POSITIVE && in_plane && length >= f32::MIN_POSITIVE {
        s.x
    } else {
        0.0
    }
}

/// Whether the `Transform` or the `ChildOf` of `entity` changed (added, set or replaced) after
/// `since`. A removal is not a change here: the callers read the removals themselves.
pub(crate) fn moved_since(
    entity: Entity,
    ticked: &TickedAncestry,
    since: Tick,
    this_run: Tick,
) -> bool {
    ticked.get(entity).is_ok_and(|(transform, parent)| {
        transform.is_some_and(|t| t.last_changed().is_newer_than(since, this_run))
            || parent.is_some_and(|p| p.last_changed().is_newer_than(since, this_run))
    })
}

/// Whether `entity` or any of its ancestors moved or was reparented after `since`
/// ([`moved_since`]), or the chain is broken (an ancestor missing, without a `Transform`, or
/// deeper than [`MAX_HIERARCHY_DEPTH`]): either way, its world pose must be composed again.
pub(crate) fn chain_moved_since(
    entity: Entity,
    ticked: &TickedAncestry,
    since: Tick,
    this_run: Tick,
) -> bool {
    let mut at = entity;
    for _ in 0..=MAX_HIERARCHY_DEPTH {
        let Ok((Some(transform), parent)) = ticked.get(at) else {
            return true;
        };
        if transform.last_changed().is_newer_than(since, this_run)
            || parent
                .as_ref()
                .is_some_and(|p| p.last_changed().is_newer_than(since, this_run))
        {
            return true;
        }
        match parent {
            Some(up) => at = up.parent(),
            None => return false,
        }
    }
    true
}

/// Pushes the ancestors of `entity` (not itself) onto `out`, as far up as the chain goes
/// (at most [`MAX_HIERARCHY_DEPTH`]).
pub(crate) fn push_ancestors(entity: Entity, ancestry: &Ancestry, out: &mut Vec<Entity>) {
    let mut at = entity;
    for _ in 0..MAX_HIERARCHY_DEPTH {
        match ancestry.get(at) {
            Ok((_, Some(parent))) => {
                at = parent.parent();
                out.push(at);
            }
            _ => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy_ecs::system::RunSystemOnce;
    use glam::{Quat, Vec3};

    fn close(a: Planar, b: Planar) -> bool {
        // A few roundings of unit-sized values.
        (a.position - b.position).length() < 1e-5
            && (a.angle - b.angle).abs() < 1e-5
            && (a.scale - b.scale).abs() < 1e-6
    }

    #[test]
    fn local_of_undoes_compose() {
        let parent = Planar {
            position: Vec2::new(3.0, -2.0),
            angle: 0.7,
            scale: 2.5,
        };
        let child = Planar {
            position: Vec2::new(-1.0, 4.0),
            angle: -1.9,
            scale: 0.5,
        };
        assert!(close(parent.local_of(parent.compose(child)), child));
        // A point at the child's origin lands where the parent's matrix sends it.
        let world = parent.compose(child);
        let m = Transform::from_translation(Vec3::new(3.0, -2.0, 0.0))
            .with_rotation(Quat::from_rotation_z(0.7))
            .with_scale(Vec3::splat(2.5));
        let expect = m.transform_point(Vec3::new(-1.0, 4.0, 0.0)).truncate();
        assert!((world.position - expect).length() < 1e-5);
    }

    #[test]
    fn chains_compose_and_bad_links_are_errors() {
        let mut world = World::new();
        let root = world
            .spawn(
                Transform::from_xyz(10.0, 0.0, 0.0)
                    .with_rotation(Quat::from_rotation_z(core::f32::consts::FRAC_PI_2))
                    .with_scale(Vec3::splat(2.0)),
            )
            .id();
        let child = world
            .spawn((Transform::from_xyz(1.0, 0.0, 0.0), ChildOf(root)))
            .id();
        let bare = world.spawn_empty().id();
        let orphan = world.spawn((Transform::IDENTITY, ChildOf(bare))).id();
        let squashed = world
            .spawn(Transform::from_scale(Vec3::new(1.0, 2.0, 1.0)))
            .id();
        let tilted = world
            .spawn(Transform::from_rotation(Quat::from_rotation_x(0.5)))
            .id();
        let results = world
            .run_system_once(move |ancestry: Ancestry| {
                [child, orphan, squashed, tilted].map(|e| pose_in(e, None, &ancestry))
            })
            .unwrap();
        let expect = Planar {
            position: Vec2::new(10.0, 2.0),
            angle: core::f32::consts::FRAC_PI_2,
            scale: 2.0,
        };
        assert!(close(results[0].unwrap(), expect), "{:?}", results[0]);
        assert_eq!(results[1], Err(CcdError::InvalidHierarchy));
        assert_eq!(results[2], Err(CcdError::UnsupportedTransform));
        assert_eq!(results[3], Err(CcdError::UnsupportedTransform));
    }
}
