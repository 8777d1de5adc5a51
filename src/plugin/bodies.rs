//! Bodies against bodies ([`CcdConfig::bodies_collide`](super::CcdConfig::bodies_collide)):
//! the step's listed and gathered bodies solved together by the geometry layer's
//! time-ordered loop ([`solve_bodies`]), with the plugin's layers, hooks and threads, and
//! their impacts with each other put into the lanes beside their impacts with targets, so
//! that the write-back, the messages and the events report them as any impact. The
//! [`Immovable`] marker.

use bevy_ecs::prelude::*;
use bevy_reflect::prelude::*;
use bevy_tasks::TaskPool;
use glam::Vec2;

use super::hooks::CcdImpactCandidate;
use super::parallel::{MAX_ITEMS, hand_out, workers};
use super::sensors::sense_lane;
use super::solve::{Rules, Shared, list_visits, own_layers, state, store};
use super::workspace::{BEYOND_LIMIT, BodyEntry, HAS_MASS, Lane};
use super::{Collider, CollisionLayers, StaticCollider};
use crate::geometry::solver::bodies::{MutualBody, MutualHit, MutualRules, solve_bodies};
use crate::geometry::solver::body_solver::MAX_PARTS;
use crate::geometry::{BodyFilter, BodyPart, ImpactRecord, ShapeProxy};

/// A CCD body other bodies never push, with
/// [`CcdConfig::bodies_collide`](super::CcdConfig::bodies_collide) on: an infinite mass to
/// them, as a [`MovingTarget`](super::MovingTarget) is. Others bounce off it; it follows its
/// user's motion (and the world's targets, as any body) whatever strikes it: a player
/// character moved by its own code, a paddle, a piston. Two immovable bodies pass through
/// each other. Without `bodies_collide` it changes nothing.
///
/// ```
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// let mut world = World::new();
/// world.spawn((
///     Collider::capsule(0.5, 0.3).unwrap(),
///     CcdEnabled::default(),
///     Immovable,
///     Transform::default(),
/// ));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default, Debug, Clone, PartialEq)]
pub struct Immovable;

/// [`ImpactRecord::target`] of an impact with another body: this bit, the other body's index
/// in the step's entries shifted by [`PART_BITS`], and its part. Targets are far fewer than
/// 2³¹, and bodies than 2²⁷ (a step's entries alone would take 13 GiB).
const BODY_TARGET: u32 = 1 << 31;
/// Bits of a body's part in a [`BODY_TARGET`] (its parts are at most [`MAX_PARTS`]).
const PART_BITS: u32 = MAX_PARTS.trailing_zeros();
const _: () = assert!(1 << PART_BITS == MAX_PARTS);

/// The [`ImpactRecord::target`] naming the body at `index` of the step's entries, part `part`.
fn body_target(index: usize, part: u32) -> u32 {
    BODY_TARGET | ((index as u32) << PART_BITS) | part
}

/// The other body (its index in the step's entries) and its part, when `target` names one
/// ([`body_target`]); `None` for a target.
pub(crate) fn other_body(target: u32) -> Option<(usize, u32)> {
    (target & BODY_TARGET != 0).then(|| {
        let rest = target & !BODY_TARGET;
        ((rest >> PART_BITS) as usize, rest & (MAX_PARTS as u32 - 1))
    })
}

/// What [`solve_bodies`] asks of the plugin: the bodies' layers and hooks, each body's
/// [`Rules`] against the world, the compute pool.
struct PluginRules<'a> {
    /// The solved bodies' entries, by their index in [`solve_bodies`].
    entries: Vec<&'a BodyEntry>,
    /// Each one's own layers (a compound body's union of its parts'), which decide which
    /// bodies meet.
    layers: Vec<CollisionLayers>,
    /// Each one's parts' layers, against the targets.
    part_layers: Vec<&'a [CollisionLayers]>,
    shared: &'a Shared<'a>,
    accept: &'a (dyn Fn(&CcdImpactCandidate) -> bool + Sync),
    pool: Option<&'a TaskPool>,
}

impl MutualRules for PluginRules<'_> {
    fn meets(&self, a: u32, b: u32) -> bool {
        self.layers[a as usize].interacts(self.layers[b as usize])
    }

    /// Each body's hook sees the other body as its target: kept when both accept.
    fn accept(&self, a: u32, b: u32, hit: &MutualHit) -> bool {
        let (ea, eb) = (self.entries[a as usize], self.entries[b as usize]);
        let compounds = self.shared.compounds;
        let candidate =
            |(body, part): (&BodyEntry, u32), (other, other_part): (&BodyEntry, u32), sign: f32| {
                CcdImpactCandidate {
                    body: body.entity,
                    body_collider: compounds.collider(body, part),
                    target: other.entity,
                    target_collider: compounds.collider(other, other_part),
                    fraction: hit.fraction,
                    point: hit.point,
                    normal: sign * hit.normal,
                    relative_velocity: sign * hit.velocity,
                    overlapping: false,
                    substep: 0,
                    other_body: Some(other.entity),
                }
            };
        let (pa, pb) = hit.parts;
        (self.accept)(&candidate((ea, pa), (eb, pb), 1.0))
            && (self.accept)(&candidate((eb, pb), (ea, pa), -1.0))
    }

    fn world(&self, body: u32) -> impl BodyFilter {
        let i = body as usize;
        Rules::new(self.entries[i], self.part_layers[i], self.shared)
    }

    /// Chunks of the items handed out over the pool ([`hand_out`]), each result written to
    /// its item's slot: the same results in the same order on any number of threads.
    fn spread<R: Send>(&self, n: usize, f: &(dyn Fn(usize) -> R + Sync)) -> Vec<R> {
        let mut slots: Vec<Option<R>> = (0..n).map(|_| None).collect();
        let chunks = (workers(self.pool) * 4).min(MAX_ITEMS).min(n).max(1);
        let len = n.div_ceil(chunks).max(1);
        hand_out(
            self.pool,
            chunks,
            &mut (),
            |_, push| {
                for (k, chunk) in slots.chunks_mut(len).enumerate() {
                    push((k * len, chunk));
                }
            },
            (
                |(start, chunk): &mut (usize, &mut [Option<R>])| {
                    for (j, slot) in chunk.iter_mut().enumerate() {
                        *slot = Some(f(*start + j));
                    }
                },
                |_: &mut _| {},
            ),
            |_, _| {},
        );
        slots
            .into_iter()
            .map(|r| r.expect("hand_out works on every item"))
            .collect()
    }
}

/// The bodies' own colliders.
type BodyColliders<'w, 's, 'c> = Query<'w, 's, &'c Collider, Without<StaticCollider>>;

/// Solves the step's bodies (`entries`, cut into `lanes` of `lane_len`) against the world and
/// against each other, ordered in time, and fills each lane as
/// [`solve_lane`](super::solve::solve_lane) does: the entries' outcomes, the impacts (with
/// targets and with bodies, in time order), the paths and sensor crossings, the lists to
/// write back. Bodies with an error are left alone. Returns the bodies clamped by the bound
/// of impacts with other bodies.
pub(crate) fn solve_together(
    (entries, lanes, lane_len): (&mut [BodyEntry], &mut [Lane], usize),
    shared: &Shared,
    (colliders, immovable): (&BodyColliders<'_, '_, '_>, &Query<(), With<Immovable>>),
    accept: &(dyn Fn(&CcdImpactCandidate) -> bool + Sync),
    pool: Option<&TaskPool>,
) -> usize {
    let compounds = shared.compounds;
    // The bodies to solve (index in `entries`) and their own collider.
    let placeholder = BodyPart {
        proxy: ShapeProxy::from_parts(&[Vec2::ZERO], 0.0),
        core_center: Vec2::ZERO,
        core_radius: 0.0,
    };
    let mut members: Vec<usize> = Vec::new();
    let mut own: Vec<BodyPart> = Vec::new();
    for (i, body) in entries.iter_mut().enumerate() {
        if !body.error.is_none_or(|e| e == BEYOND_LIMIT) {
            continue;
        }
        let mut part = placeholder;
        match compounds.read(body, colliders, &mut part) {
            Ok(mass) => {
                if body.flags & HAS_MASS == 0 {
                    body.mass = mass.mass;
                    body.inertia = mass.inertia;
                }
                members.push(i);
                own.push(part);
            }
            Err(error) => body.error = Some(error),
        }
    }
    let outcome = {
        let entries: &[BodyEntry] = entries;
        let layers: Vec<[CollisionLayers; 1]> = members
            .iter()
            .map(|&i| [own_layers(&entries[i], shared)])
            .collect();
        let parts: Vec<(&[BodyPart], &[CollisionLayers])> = members
            .iter()
            .zip(&own)
            .zip(&layers)
            .map(|((&i, part), layers)| {
                let (parts, part_layers) = compounds.parts_of(&entries[i], part);
                (parts, part_layers.unwrap_or(layers))
            })
            .collect();
        let bodies: Vec<MutualBody> = members
            .iter()
            .zip(&parts)
            .map(|(&i, &(parts, _))| MutualBody {
                state: state(&entries[i]),
                parts,
                immovable: immovable.contains(entries[i].entity),
            })
            .collect();
        let rules = PluginRules {
            entries: members.iter().map(|&i| &entries[i]).collect(),
            layers: layers.iter().map(|l| l[0]).collect(),
            part_layers: parts.iter().map(|p| p.1).collect(),
            shared,
            accept,
            pool,
        };
        solve_bodies(&bodies, shared.statics, shared.settings, &rules)
    };
    // Each impact between two bodies as an impact of each, naming the other, by body then
    // time.
    let mut mutual: Vec<(usize, ImpactRecord)> = Vec::with_capacity(2 * outcome.impacts.len());
    for m in &outcome.impacts {
        let (a, b) = (members[m.a as usize], members[m.b as usize]);
        let record = |target, part, normal| ImpactRecord {
            target,
            part,
            fraction: m.fraction,
            point: m.point,
            normal,
        };
        mutual.push((a, record(body_target(b, m.part_b), m.part_a, m.normal)));
        mutual.push((b, record(body_target(a, m.part_a), m.part_b, -m.normal)));
    }
    mutual.sort_by(|x, y| x.0.cmp(&y.0).then(x.1.fraction.total_cmp(&y.1.fraction)));
    let (mut runs, mut mutual) = (
        members.iter().zip(&outcome.runs).peekable(),
        mutual.into_iter().peekable(),
    );
    for (l, lane) in lanes.iter_mut().enumerate() {
        let first = l * lane_len;
        let end = (first + lane_len).min(entries.len());
        let chunk = &mut entries[first..end];
        lane.impacts.clear();
        lane.hit.clear();
        lane.visit.clear();
        lane.sensing.path.clear();
        lane.sensing.paths.clear();
        for (index, body) in chunk.iter_mut().enumerate() {
            let Some((_, run)) = runs.next_if(|(i, _)| **i == first + index) else {
                continue;
            };
            store(body, run.outcome);
            // Impacts with targets and with bodies, merged in time order (targets first on a
            // tie).
            body.impacts = lane.impacts.len() as u32;
            let mut world = run.impacts.iter().peekable();
            loop {
                let next_mutual = mutual.peek().filter(|(i, _)| *i == first + index);
                let record = match (world.peek(), next_mutual) {
                    (Some(w), Some((_, m))) if m.fraction < w.fraction => {
                        mutual.next().map(|m| m.1)
                    }
                    (Some(_), _) => world.next().copied(),
                    (None, Some(_)) => mutual.next().map(|m| m.1),
                    (None, None) => None,
                };
                let Some(record) = record else { break };
                lane.impacts.push(record);
            }
            let count = lane.impacts.len() - body.impacts as usize;
            body.impact_count = count.min(u16::MAX as usize) as u16;
            if shared.paths {
                let from = lane.sensing.path.len();
                lane.sensing.path.extend_from_slice(&run.path);
                lane.sensing.traced(index, from);
            }
        }
        if let Some(sensors) = shared.sensors {
            sense_lane(chunk, lane, sensors, colliders, shared);
        }
        list_visits(chunk, lane);
    }
    outcome.clamped as usize
}
