//! The write-back of a solved lane: the bodies' `Transform`s, [`Velocity`]s and
//! [`CcdOutcome`]s, and the resolved pose the next step may start from.

use bevy_ecs::prelude::*;
use bevy_transform::components::Transform;
use glam::Quat;

use super::bodies::other_body;
use super::compound::Compounds;
use super::hierarchy::Planar;
use super::outcome::{CcdError, CcdHits, CcdImpact, CcdOutcome};
use super::workspace::{BodyEntry, HAS_VELOCITY, Lane, NUDGED, OVERLAPPING};
use super::{StaticCollider, StepPoses, Velocity};
use crate::geometry::ImpactRecord;

/// Puts a body in the error state, with a warning the first time this error shows (the
/// settings' errors have their own, once for every body). An error repeated from the last step
/// is left unwritten (no change flagged).
fn set_error(toi: &mut Mut<CcdOutcome>, entity: Entity, error: CcdError) {
    let outcome = CcdOutcome::Error(error);
    if **toi != outcome {
        if toi.error() != Some(error) && error != CcdError::InvalidSettings {
            match error {
                CcdError::Toi(_) => log::warn!(
                    "bevy_ccd: body {entity}: {error:?}; stopped at the last pose known to be clear"
                ),
                _ => log::warn!(
                    "bevy_ccd: body {entity} not swept this step: {error:?}; left where it is"
                ),
            }
        }
        **toi = outcome;
    }
}

/// The query the write-back writes through.
pub(crate) type WriteQuery<'w, 's> = Query<
    'w,
    's,
    (
        &'static mut Transform,
        &'static mut StepPoses,
        Option<&'static mut Velocity>,
        &'static mut CcdOutcome,
    ),
    Without<StaticCollider>,
>;

/// Writes one solved lane back: poses, velocities and outcomes of the bodies on its `visit`
/// list, those with impacts, errors or overlaps, and those whose outcome was not clear
/// before. The others (most bodies, most steps) were clear and stay clear, at the end pose
/// `record_end` already wrote as resolved.
///
/// A child body's poses are world poses; its resolved one is written back as the local
/// `Transform` that gives it under its parent as the parent was at
/// [`record_end`](super::record::record_end) (`parent.local_of(world)`, the user's z and
/// scale kept). A child body whose chain has no world pose gets the error that says why.
pub(crate) fn write_lane(
    chunk: &[BodyEntry],
    lane: &Lane,
    bodies: &mut WriteQuery,
    targets: &WriteLookups,
    compounds: &Compounds,
) {
    for &index in &lane.visit {
        let body = &chunk[index as usize];
        // The entity was gathered this step, so it is there: the same schedule pass solves
        // and writes it.
        let Ok((mut transform, mut sweep, velocity, mut toi)) = bodies.get_mut(body.entity) else {
            continue;
        };
        let failed =
            matches!(body.error, Some(e) if !matches!(e, CcdError::Toi(_) | CcdError::Squeezed));
        if failed {
            sweep.bypass_change_detection().resolved_valid = false;
            let mut error = body.error.unwrap_or(CcdError::InvalidBodyData);
            // The record passes leave a child body without a world pose at NaN.
            if error == CcdError::NonFiniteTransform
                && let Some(Err(why)) = targets.frame(body.entity)
            {
                error = why;
            }
            set_error(&mut toi, body.entity, error);
            continue;
        }
        // Without an impact or a failure the body ends where its user put it: that pose
        // is left exactly as it is (the solver's went through the centre of mass and
        // back, and a rebuilt rotation would not have the user's bits).
        let (position, angle) =
            if body.impact_count == 0 && body.error.is_none() && body.flags & NUDGED == 0 {
                (sweep.end_position, sweep.end_angle)
            } else {
                (body.position, body.angle)
            };
        if position != sweep.end_position || angle != sweep.end_angle {
            let (local, local_angle) = match targets.frame(body.entity) {
                Some(Ok(parent)) => {
                    let local = parent.local_of(Planar {
                        position,
                        angle,
                        scale: parent.scale,
                    });
                    (local.position, local.angle)
                }
                _ => (position, angle),
            };
            transform.translation.x = local.x;
            transform.translation.y = local.y;
            transform.rotation = turned(transform.rotation, local_angle, angle - sweep.end_angle);
        }
        let sweep = sweep.bypass_change_detection();
        sweep.resolved_position = position;
        sweep.resolved_angle = angle;
        sweep.resolved_valid = true;
        if let Some(mut v) = velocity
            && body.flags & HAS_VELOCITY != 0
            && (v.linear != body.velocity || v.angular != body.angular)
        {
            v.linear = body.velocity;
            v.angular = body.angular;
        }
        let hits = (body.impact_count > 0).then(|| CcdHits {
            first: targets.impact(body, &lane.impacts[body.impacts as usize], 0, compounds),
            count: body.impact_count as u32,
            substeps: body.substeps as u32,
        });
        let outcome = match (body.error, hits) {
            (Some(error), _) => {
                // Stopped where the time of impact failed, or at the limit: a warning.
                set_error(&mut toi, body.entity, error);
                continue;
            }
            (None, hits) if body.flags & OVERLAPPING != 0 => CcdOutcome::Overlapping(hits),
            (None, Some(hits)) => CcdOutcome::Hit(hits),
            (None, None) => CcdOutcome::Clear,
        };
        // Leave an unchanged outcome untouched (no change flagged to the user's
        // `Changed<TimeOfImpact>` filters).
        if *toi != outcome {
            *toi = outcome;
        }
    }
}

/// The rotation written back for a body the step turned to `local_angle` about z, `turn` away
/// from where its user left it, `user`: only the rotation about z changes. An upright body
/// (`user` about z alone, the common case) gets the plain rotation by `local_angle`; one with a
/// part out of the plane (a sprite mirrored by a half turn about y, a slight tilt) gets `user`
/// turned by `turn` about z, so that its part out of the plane stays: a mirror's z and w stay
/// exactly 0.
#[inline]
fn turned(user: Quat, local_angle: f32, turn: f32) -> Quat {
    if user.x == 0.0 && user.y == 0.0 {
        Quat::from_rotation_z(local_angle)
    } else {
        Quat::from_rotation_z(turn) * user
    }
}

/// What the write-back reads of the workspace besides the lane: each item's target and
/// collider entity, this step's child bodies' parent poses, and the bodies (the other body of
/// an impact between two).
pub(crate) struct WriteLookups<'a> {
    pub(crate) entities: &'a [Entity],
    pub(crate) colliders: &'a [Entity],
    pub(crate) child_frames: &'a [(Entity, Result<Planar, CcdError>)],
    pub(crate) bodies: &'a [BodyEntry],
}

impl WriteLookups<'_> {
    /// The [`CcdImpact`] of `body`'s impact `record`, the `substep`-th of its step: the
    /// entities of its colliders and of the target.
    pub(crate) fn impact(
        &self,
        body: &BodyEntry,
        record: &ImpactRecord,
        substep: u32,
        compounds: &Compounds,
    ) -> CcdImpact {
        let (target, target_collider, other_body) = match other_body(record.target) {
            Some((index, part)) => {
                let other = &self.bodies[index];
                let entity = other.entity;
                (entity, compounds.collider(other, part), Some(entity))
            }
            None => (
                self.entities[record.target as usize],
                self.colliders[record.target as usize],
                None,
            ),
        };
        CcdImpact {
            body: body.entity,
            body_collider: compounds.collider(body, record.part),
            target,
            target_collider,
            other_body,
            fraction: record.fraction,
            point: record.point,
            normal: record.normal,
            substep,
        }
    }

    /// A child body's parent pose, or why its chain has none; `None` for a root body. Looked
    /// up only when the step has child bodies, so that a world without them pays one test
    /// per written body.
    #[inline]
    fn frame(&self, entity: Entity) -> Option<Result<Planar, CcdError>> {
        if self.child_frames.is_empty() {
            return None;
        }
        let at = self
            .child_frames
            .binary_search_by_key(&entity, |(e, _)| *e)
            .ok()?;
        Some(self.child_frames[at].1)
    }
}
