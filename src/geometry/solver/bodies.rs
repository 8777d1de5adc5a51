//! Bodies against bodies, ordered in time ([`solve_bodies`]): as Box2D v2.4's `SolveTOI`
//! (Catto, "Continuous Collision", GDC 2013), on the one body path of [`solve_body`].
//!
//! 1. **Each body alone.** Every body is solved against the world as without other bodies
//!    ([`solve_body`]): its *path* over the step is the list of sweeps it travelled
//!    ([`PathPiece`]), completed to the step's end (a body clamped at `t` stands still from
//!    there).
//! 2. **Islands.** Two bodies are a candidate pair when the boxes of their paths meet (grown by
//!    the slop; sort and sweep along x, [`candidate_pairs`]), both may move (two immovable bodies
//!    never meet) and the caller's `meets` lets them (collision layers). Bodies connected
//!    through pairs are an island (union-find, the lower index the root); islands are solved
//!    independently, each in a fixed order, their results written by body index, so the
//!    answer is the same whatever solves them and on how many threads.
//! 3. **Time-ordered loop, per island.** Every pair's earliest impact along the two current
//!    paths, at or after the island's clock `T`, is searched piece against piece where the two
//!    paths overlap in time (each a two-sweep time of impact, the other body as a moving target,
//!    [`pair_toi`]). The earliest wins (ties to the lower pair); both bodies are advanced to it,
//!    the impulse between them acts ([`mutual_response`], restitution the larger of the two,
//!    friction their geometric mean, as Box2D mixes them); then, in `SubStep`, each body that
//!    can be pushed is solved against the world again from that time to the end of the step
//!    ([`solve_body_from`]) and its path after it replaced; in `Clamp` both stop there for the
//!    rest of the step (with their new velocities), unless the other is an infinite mass
//!    (immovable or clamped): that one may go on, as a moving target does, so the body goes on
//!    too. Riding a mover, a body's path follows the mover's turn in chords within half the
//!    slop of the arc ([`follow`]). `T` moves to the impact; only the two
//!    bodies' pairs are searched again (no pair had an impact before `T`), and a body's new
//!    path is tested against every body of its island for new pairs. Repeat until no pair hits.
//! 4. **Closing the islands.** A body's new path can reach a body of another island: once
//!    every island is solved, the pairs are found again over the union of every path each body
//!    has had; islands that merged are solved again from step 1's paths. Merges only grow, so
//!    this ends, and in the common case (paths inside their boxes) after one round.
//!
//! Contacts at the clock (a body resting on another, or one just struck and still touching):
//! a pair that starts a stretch touching is a hit at once only when its points approach
//! (`pair_toi`'s test on the contact patch, as a body's start contacts); a response leaves
//! them at rest or separating, so a resting pair is searched once and is clear. Newton's cradle
//! passes the impulse ball to ball at the same instant, each a hit at the clock.
//!
//! **Bound.** A body takes at most [`MAX_BODY_IMPACTS`] impacts with other bodies in a step;
//! at the next it is clamped where it is for the rest of the step (counted in
//! [`BodiesOutcome::clamped`]) and is an infinite mass to the others from then on. An immovable
//! body is an infinite mass throughout, as a moving target: it follows its own path, never
//! pushed. A clamped body stands, unless something moving with infinite mass strikes it:
//!
//! **Infinite against infinite.** Neither gives way by the masses, yet one must, or the two
//! (or the mover driving one of them, a blade turning through a pile) end in each other. The
//! rule: a moving target that strikes a clamped body pushes it as it pushes any body (the
//! world's solve of it, [`stand`]); a pair of two infinite masses stays searched, and at its
//! impact the struck side (the clamped one, of two clamped the one moving the less toward
//! the other) is pushed by the other as by a moving target (the impulse against an infinite
//! mass, then solved on against the world in both modes). Pushing two bodies apart can fail
//! to settle (a pile driven by a blade, each push sending one back into the other), so after
//! [`MAX_BODY_IMPACTS`] pushes a body struck again is *held*: carried rigidly with the body
//! that struck it for the rest of the step ([`hold`], along the other's path, the world not
//! searched on the way), as a body out of sub-steps rides a mover; after as many holds the
//! pair is left to pass (a true squeeze, such as two immovable bodies closing on one).
//! Every impact counts against one body's bound (of impacts, pushes or holds) or clamps it:
//! an island of `n` bodies resolves at most `n (3 MAX_BODY_IMPACTS + 1)` impacts.
//!
//! **Failures.** A pair's time of impact that fails, or an impulse that fails (a zero or
//! non-finite mass, a velocity beyond `f32` after the impulse), clamps both bodies at that time
//! with the failure in their outcomes; other bodies are not touched.

use core::cmp::{Ordering, Reverse};
use core::ops::{Index, IndexMut};
use std::collections::{BinaryHeap, HashSet};

use glam::Vec2;

use crate::geometry::constants::MAX_BODY_IMPACTS;
use crate::geometry::query::toi::{BodyFrame, ToiFailure};
use crate::geometry::shape::Aabb;
use crate::geometry::solver::body_solver::{
    BodyFilter, BodyOutcome, BodyPart, BodyState, ImpactRecord, MAX_PARTS, Resolution,
    SolveSettings, follow, held_by, solve_body_from,
};
use crate::geometry::solver::mutual::{Side, mutual_response};
use crate::geometry::solver::pair::{Contact, PairOutcome, contact_patch, pair_toi};
use crate::geometry::solver::sensor::PathPiece;
use crate::geometry::solver::static_set::{StaticItem, StaticSet, TargetFrame};
use crate::geometry::sweep::Sweep;

/// One body as [`solve_bodies`] takes it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MutualBody<'a> {
    /// Its motion over the step, mass and material.
    pub(crate) state: BodyState,
    /// Its colliders (at least one to meet anything).
    pub(crate) parts: &'a [BodyPart],
    /// Never pushed by another body (infinite mass): others bounce off it, it follows its sweep
    /// and the world as a body alone does.
    pub(crate) immovable: bool,
}

/// One body's step: its outcome, its path over the whole step and its impacts with the world.
#[derive(Clone, Debug)]
pub(crate) struct BodyRun {
    /// Where it ends, its velocity and state, as [`solve_body`] gives them.
    pub(crate) outcome: BodyOutcome,
    /// The sweeps it travelled, in order, from fraction 0 to 1 of the step.
    pub(crate) path: Vec<PathPiece>,
    /// Its impacts with the world, in time order.
    pub(crate) impacts: Vec<ImpactRecord>,
    /// Impacts with other bodies this step.
    pub(crate) mutual: u32,
    /// Clamped after [`MAX_BODY_IMPACTS`] impacts with other bodies: stands still for the rest
    /// of the step (unless a moving target or a body of infinite mass drives it), an infinite
    /// mass to the others.
    pub(crate) clamped: bool,
    /// Times it was pushed this step, clamped, by another body of infinite mass (at most
    /// [`MAX_BODY_IMPACTS`]).
    pub(crate) driven: u32,
}

/// An impact between two bodies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MutualImpact {
    /// The lower body index of the pair.
    pub(crate) a: u32,
    /// The higher.
    pub(crate) b: u32,
    /// A's part that met B.
    pub(crate) part_a: u32,
    /// B's part that met A.
    pub(crate) part_b: u32,
    /// Fraction of the step.
    pub(crate) fraction: f32,
    /// Contact point (world).
    pub(crate) point: Vec2,
    /// Unit normal from B toward A.
    pub(crate) normal: Vec2,
}

/// What [`solve_bodies`] did.
#[derive(Clone, Debug, Default)]
pub(crate) struct BodiesOutcome {
    /// Per body, by index.
    pub(crate) runs: Vec<BodyRun>,
    /// Impacts between bodies, island by island (by their lowest body), each island's in time
    /// order.
    pub(crate) impacts: Vec<MutualImpact>,
    /// Bodies clamped after [`MAX_BODY_IMPACTS`] impacts with other bodies.
    pub(crate) clamped: u32,
}

/// What the caller decides of bodies meeting ([`solve_bodies`]): which pairs may collide
/// (collision layers), whether an impact between two is kept (hooks), the filter each body
/// meets the world with, and how independent work is spread over threads. A closure
/// `Fn(u32, u32) -> bool` is `meets` alone: every impact kept, the world unfiltered, one
/// thread.
pub(crate) trait MutualRules: Sync {
    /// Whether bodies `a` and `b` (`a < b`) may collide.
    fn meets(&self, a: u32, b: u32) -> bool;
    /// Whether the impact `hit` between bodies `a` and `b` is responded to; a rejected pair
    /// is ignored for the rest of the step, as a rejected target is.
    fn accept(&self, a: u32, b: u32, hit: &MutualHit) -> bool;
    /// The filter body `body` meets the world with.
    fn world(&self, body: u32) -> impl BodyFilter;
    /// `f(0), f(1), ..., f(n - 1)`, in that order whatever thread computed each: the items
    /// are independent, so the answer is the same bits on one thread or many.
    fn spread<R: Send>(&self, n: usize, f: &(dyn Fn(usize) -> R + Sync)) -> Vec<R> {
        (0..n).map(f).collect()
    }
}

impl<F: Fn(u32, u32) -> bool + Sync> MutualRules for F {
    fn meets(&self, a: u32, b: u32) -> bool {
        self(a, b)
    }
    fn accept(&self, _: u32, _: u32, _: &MutualHit) -> bool {
        true
    }
    fn world(&self, _: u32) -> impl BodyFilter {}
}

/// An impact between two bodies about to be responded to, as [`MutualRules::accept`] sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MutualHit {
    /// A's part that meets B, and B's that meets A.
    pub(crate) parts: (u32, u32),
    /// Fraction of the step.
    pub(crate) fraction: f32,
    /// Contact point (world).
    pub(crate) point: Vec2,
    /// Unit normal from B toward A.
    pub(crate) normal: Vec2,
    /// A's velocity at the point relative to B's as they meet (m/s): negative along `normal`
    /// when they approach.
    pub(crate) velocity: Vec2,
}

/// Solves every body against the world and against the others, ordered in time (see the
/// module's documentation). `rules` say which pairs meet and which impacts count, give each
/// body's world filter and spread the bodies alone and the islands over threads.
/// Deterministic: the answer depends only on the inputs.
pub(crate) fn solve_bodies(
    bodies: &[MutualBody],
    statics: &StaticSet,
    settings: &SolveSettings,
    rules: &impl MutualRules,
) -> BodiesOutcome {
    let alone: Vec<BodyRun> = rules.spread(bodies.len(), &|i| {
        solve_alone(&bodies[i], &rules.world(i as u32), statics, settings)
    });
    let slop = settings.linear_slop;
    let mut bounds: Vec<Aabb> = bodies
        .iter()
        .zip(&alone)
        .map(|(b, r)| path_bounds(b.parts, &r.path))
        .collect();
    let mut runs = alone.clone();
    // The islands solved so far, with their impacts.
    let mut solved: Vec<(Vec<u32>, Vec<MutualImpact>)> = Vec::new();
    loop {
        let pairs = candidate_pairs(bodies, &bounds, slop, rules);
        let islands = islands(bodies.len(), &pairs);
        // Each island's pairs, by its place in the list.
        let mut slot = vec![usize::MAX; bodies.len()];
        for (k, island) in islands.iter().enumerate() {
            for &i in island {
                slot[i as usize] = k;
            }
        }
        let mut island_pairs = vec![Vec::new(); islands.len()];
        for &(a, b) in &pairs {
            island_pairs[slot[a as usize]].push((a, b));
        }
        // An island solved before with exactly these bodies keeps its answer; any other is a
        // merge of earlier ones (or new), solved afresh from the bodies' paths alone.
        let todo: Vec<Island> = islands
            .into_iter()
            .zip(island_pairs)
            .filter(|(island, _)| !solved.iter().any(|(s, _)| s == island))
            .collect();
        if todo.is_empty() {
            break;
        }
        for (island, _) in &todo {
            solved.retain(|(s, _)| island.binary_search(&s[0]).is_err());
        }
        // Islands are independent: each starts from its bodies' paths alone.
        let answers = rules.spread(todo.len(), &|k| {
            let (island, pairs) = &todo[k];
            let mut local = IslandRuns {
                island,
                runs: island.iter().map(|&i| alone[i as usize].clone()).collect(),
            };
            let impacts = solve_island(
                (island, pairs),
                bodies,
                &mut local,
                statics,
                settings,
                rules,
            );
            (local.runs, impacts)
        });
        for ((island, _), (island_runs, impacts)) in todo.into_iter().zip(answers) {
            for (&i, run) in island.iter().zip(island_runs) {
                runs[i as usize] = run;
            }
            solved.push((island, impacts));
        }
        for (i, (body, run)) in bodies.iter().zip(&runs).enumerate() {
            bounds[i] = bounds[i].union(path_bounds(body.parts, &run.path));
        }
    }
    solved.sort_by_key(|(island, _)| island[0]);
    BodiesOutcome {
        clamped: runs.iter().filter(|r| r.clamped).count() as u32,
        runs,
        impacts: solved.into_iter().flat_map(|(_, i)| i).collect(),
    }
}

/// An island: its bodies (ascending) and its candidate pairs.
type Island = (Vec<u32>, Vec<(u32, u32)>);

/// The runs of one island's bodies, looked up by body index.
struct IslandRuns<'a> {
    /// The island's bodies, ascending.
    island: &'a [u32],
    /// Their runs, in the same order.
    runs: Vec<BodyRun>,
}

impl Index<usize> for IslandRuns<'_> {
    type Output = BodyRun;
    fn index(&self, body: usize) -> &BodyRun {
        let at = self.island.binary_search(&(body as u32));
        &self.runs[at.expect("a body of the island")]
    }
}

impl IndexMut<usize> for IslandRuns<'_> {
    fn index_mut(&mut self, body: usize) -> &mut BodyRun {
        let at = self.island.binary_search(&(body as u32));
        &mut self.runs[at.expect("a body of the island")]
    }
}

/// A body solved against the world alone, its path completed to the step's end.
fn solve_alone(
    body: &MutualBody,
    filter: &impl BodyFilter,
    statics: &StaticSet,
    settings: &SolveSettings,
) -> BodyRun {
    let mut run = BodyRun {
        outcome: BodyOutcome {
            position: body.state.sweep.pose_at(0.0).p,
            angle: body.state.sweep.a0,
            velocity: body.state.velocity,
            impacts: 0,
            substeps: 0,
            started_overlapping: false,
            failure: None,
            nudged: false,
            squeezed: false,
        },
        path: Vec::new(),
        impacts: Vec::new(),
        mutual: 0,
        clamped: false,
        driven: 0,
    };
    resolve_from(
        0.0,
        (body, filter),
        &body.state,
        &mut run,
        statics,
        settings,
    );
    run
}

/// Solves `body` against the world from fraction `start` along `state.sweep` (which covers
/// `[start, 1]`), replacing its path and impacts after `start` and its outcome.
fn resolve_from(
    start: f32,
    (body, filter): (&MutualBody, &impl BodyFilter),
    state: &BodyState,
    run: &mut BodyRun,
    statics: &StaticSet,
    settings: &SolveSettings,
) {
    let parts = &body.parts[..body.parts.len().min(MAX_PARTS)];
    let mut candidates = Vec::new();
    if let Some(bounds) = parts_bounds(parts, &state.sweep) {
        statics.candidates_in(bounds, settings.linear_slop, &mut candidates);
    }
    let mut impacts = Vec::new();
    let mut path = Vec::new();
    let out = solve_body_from(
        start,
        state,
        parts,
        statics,
        &candidates,
        settings,
        (&mut Vec::new(), &mut impacts),
        filter,
        Some(&mut path),
    );
    cut_path(&mut run.path, start);
    run.path.extend(path);
    complete_path(&mut run.path, state.local_center, &out);
    run.impacts.retain(|i| i.fraction <= start);
    run.impacts.extend(impacts);
    run.outcome = BodyOutcome {
        impacts: run.impacts.len() as u32,
        substeps: run.outcome.substeps + out.substeps,
        started_overlapping: run.outcome.started_overlapping || out.started_overlapping,
        nudged: run.outcome.nudged || out.nudged,
        velocity: if body.state.velocity.is_some() {
            out.velocity
        } else {
            None
        },
        ..out
    };
}

/// Keeps the part of `path` before fraction `t`.
fn cut_path(path: &mut Vec<PathPiece>, t: f32) {
    path.retain(|p| p.from < t);
    if let Some(last) = path.last_mut()
        && last.to > t
    {
        let u = (t - last.from) / (last.to - last.from);
        let s = last.sweep;
        last.sweep = Sweep::new(s.local_center, s.c0, s.a0, s.center_at(u), s.angle_at(u));
        last.to = t;
    }
}

/// Appends to `path` the stretch from its end (fraction and pose) to where `out` left the body
/// at the step's end: the body stands still after a clamp, or rides a mover.
fn complete_path(path: &mut Vec<PathPiece>, local_center: Vec2, out: &BodyOutcome) {
    let end = Sweep::from_origins(
        local_center,
        out.position,
        out.angle,
        out.position,
        out.angle,
    );
    let (from, c0, a0) = match path.last() {
        Some(p) => (p.to, p.sweep.c1, p.sweep.a1),
        None => (0.0, end.c0, end.a0),
    };
    if from < 1.0 {
        path.push(PathPiece {
            sweep: Sweep::new(local_center, c0, a0, end.c1, end.a1),
            from,
            to: 1.0,
        });
    }
}

/// The box of every part over `sweep`, `None` without parts.
fn parts_bounds(parts: &[BodyPart], sweep: &Sweep) -> Option<Aabb> {
    parts
        .iter()
        .map(|p| p.proxy.swept_aabb(sweep))
        .reduce(Aabb::union)
}

/// The box of every part over every piece of `path`; an empty box far away without parts.
fn path_bounds(parts: &[BodyPart], path: &[PathPiece]) -> Aabb {
    let parts = &parts[..parts.len().min(MAX_PARTS)];
    path.iter()
        .filter_map(|p| parts_bounds(parts, &p.sweep))
        .reduce(Aabb::union)
        .unwrap_or(Aabb {
            min: Vec2::splat(f32::INFINITY),
            max: Vec2::splat(f32::NEG_INFINITY),
        })
}

/// The pairs `(a, b)`, `a < b`, whose boxes meet (grown by `slop`), that may move and that
/// `meets` lets collide, in ascending order: sort and sweep along x.
fn candidate_pairs(
    bodies: &[MutualBody],
    bounds: &[Aabb],
    slop: f32,
    rules: &impl MutualRules,
) -> Vec<(u32, u32)> {
    let mut order: Vec<u32> = (0..bounds.len() as u32)
        .filter(|&i| {
            let b = &bounds[i as usize];
            b.min.x <= b.max.x && !bodies[i as usize].parts.is_empty()
        })
        .collect();
    order.sort_by(|&i, &j| {
        bounds[i as usize]
            .min
            .x
            .total_cmp(&bounds[j as usize].min.x)
            .then(i.cmp(&j))
    });
    let mut pairs = Vec::new();
    let mut active: Vec<u32> = Vec::new();
    for &i in &order {
        let bi = bounds[i as usize].expanded(slop);
        active.retain(|&j| bounds[j as usize].max.x >= bi.min.x);
        for &j in &active {
            let (a, b) = (i.min(j), i.max(j));
            let both_fixed = bodies[a as usize].immovable && bodies[b as usize].immovable;
            if !both_fixed && bi.overlaps(&bounds[j as usize]) && rules.meets(a, b) {
                pairs.push((a, b));
            }
        }
        active.push(i);
    }
    pairs.sort_unstable();
    pairs
}

/// The islands of `n` bodies joined by `pairs` (only those in some pair), each sorted, in
/// order of their lowest body.
fn islands(n: usize, pairs: &[(u32, u32)]) -> Vec<Vec<u32>> {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            let up = parent[parent[i as usize] as usize];
            parent[i as usize] = up;
            i = up;
        }
        i
    }
    for &(a, b) in pairs {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
    let mut in_pair = vec![false; n];
    for &(a, b) in pairs {
        in_pair[a as usize] = true;
        in_pair[b as usize] = true;
    }
    let mut islands: Vec<Vec<u32>> = Vec::new();
    let mut slot = vec![usize::MAX; n];
    for i in 0..n as u32 {
        if !in_pair[i as usize] {
            continue;
        }
        let r = root(&mut parent, i) as usize;
        if slot[r] == usize::MAX {
            slot[r] = islands.len();
            islands.push(Vec::new());
        }
        islands[slot[r]].push(i);
    }
    islands
}

/// The earliest thing a pair's paths meet with at or after the clock.
#[derive(Clone, Copy, Debug)]
enum Meeting {
    Hit {
        fraction: f32,
        parts: (u32, u32),
        contact: Contact,
    },
    Failed {
        fraction: f32,
        failure: ToiFailure,
    },
}

impl Meeting {
    fn fraction(&self) -> f32 {
        match *self {
            Self::Hit { fraction, .. } | Self::Failed { fraction, .. } => fraction,
        }
    }
}

/// `piece`'s sweep over the fractions `[lo, hi]` of the step.
fn sub_sweep(piece: &PathPiece, lo: f32, hi: f32) -> Sweep {
    let span = piece.to - piece.from;
    let u = |t: f32| {
        if span > 0.0 {
            ((t - piece.from) / span).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let s = &piece.sweep;
    let (u0, u1) = (u(lo), u(hi));
    Sweep::new(
        s.local_center,
        s.center_at(u0),
        s.angle_at(u0),
        s.center_at(u1),
        s.angle_at(u1),
    )
}

/// The earliest meeting of bodies `a` and `b` along their paths at or after `clock`: the
/// stretches where their pieces overlap in time, in order, each a two-sweep time of impact of
/// every part of A against every part of B (B as a moving target). Sets `overlapped` when two
/// parts overlap at the step's start.
fn pair_meeting(
    (a, run_a): (&MutualBody, &BodyRun),
    (b, run_b): (&MutualBody, &BodyRun),
    clock: f32,
    slop: f32,
    overlapped: &mut bool,
) -> Option<Meeting> {
    let (parts_a, parts_b) = (
        &a.parts[..a.parts.len().min(MAX_PARTS)],
        &b.parts[..b.parts.len().min(MAX_PARTS)],
    );
    let (mut i, mut j) = (0, 0);
    while i < run_a.path.len() && j < run_b.path.len() {
        let (pa, pb) = (&run_a.path[i], &run_b.path[j]);
        let lo = pa.from.max(pb.from).max(clock);
        let hi = pa.to.min(pb.to);
        if lo < hi {
            let (sa, sb) = (sub_sweep(pa, lo, hi), sub_sweep(pb, lo, hi));
            let mut best: Option<Meeting> = None;
            for (ka, part_a) in parts_a.iter().enumerate() {
                let box_a = part_a.proxy.swept_aabb(&sa).expanded(slop);
                let reach = part_a.proxy.max_distance_from(sa.local_center);
                let frame_a = BodyFrame::with_reach(&sa, reach);
                for (kb, part_b) in parts_b.iter().enumerate() {
                    if !box_a.overlaps(&part_b.proxy.swept_aabb(&sb)) {
                        continue;
                    }
                    let start = sb.pose_at(0.0);
                    let item = StaticItem {
                        proxy: part_b.proxy,
                        position: start.p,
                        angle: sb.a0,
                    };
                    let mut frame = TargetFrame::new(&item);
                    frame.toi = BodyFrame::new(&sb, &part_b.proxy);
                    let t_max = best.map_or(1.0, |m| (m.fraction() - lo) / (hi - lo));
                    let at = |u: f32| (lo + u * (hi - lo)).min(hi);
                    let found = match pair_toi(
                        part_a,
                        reach,
                        &sa,
                        frame_a,
                        (&item, &frame, Some(&sb)),
                        slop,
                        (0.0, t_max.clamp(0.0, 1.0)),
                        None,
                    ) {
                        PairOutcome::Hit {
                            fraction,
                            contact,
                            overlapping,
                            ..
                        } => {
                            *overlapped |= overlapping && lo == 0.0;
                            Meeting::Hit {
                                fraction: at(fraction),
                                parts: (ka as u32, kb as u32),
                                contact,
                            }
                        }
                        PairOutcome::Failed { fraction, failure } => Meeting::Failed {
                            fraction: at(fraction),
                            failure,
                        },
                        // Too close to search from (at the start, in each other): the
                        // bodies separate along it now.
                        PairOutcome::Nudge(offset) => {
                            *overlapped |= lo == 0.0;
                            Meeting::Hit {
                                fraction: lo,
                                parts: (ka as u32, kb as u32),
                                contact: Contact {
                                    point: sa.center_at(0.0),
                                    normal: -offset.normalize_or(Vec2::X),
                                    separation: 0.0,
                                    patch: None,
                                },
                            }
                        }
                        PairOutcome::Clear { overlapping, .. } => {
                            *overlapped |= overlapping && lo == 0.0;
                            continue;
                        }
                    };
                    if best.is_none_or(|m| found.fraction() < m.fraction()) {
                        best = Some(found);
                    }
                }
            }
            if best.is_some() {
                return best;
            }
        }
        // The piece that ends first gives way.
        if pa.to <= pb.to {
            i += 1;
        } else {
            j += 1;
        }
    }
    None
}

/// Centre of mass, angle and velocity of a body at fraction `t` along its path: the piece
/// it is travelling from `t` on (the last at the step's end).
fn state_at(path: &[PathPiece], t: f32, dt: f32) -> (Vec2, f32, (Vec2, f32)) {
    let piece = path
        .iter()
        .find(|p| p.from <= t && t < p.to)
        .or(path.last())
        .expect("a completed path has a piece");
    let s = sub_sweep(piece, t, piece.to);
    let span = (piece.to - t) * dt;
    let velocity = if span > 0.0 {
        (s.linear_motion() / span, s.angular_motion() / span)
    } else {
        (Vec2::ZERO, 0.0)
    };
    (s.c0, s.a0, velocity)
}

/// Stops a body at fraction `t` for the rest of the step, with `velocity` as its own (when it
/// keeps one) and `failure` if any.
fn stop_at(
    body: &MutualBody,
    run: &mut BodyRun,
    t: f32,
    velocity: (Vec2, f32),
    failure: Option<ToiFailure>,
) {
    let (c, a, _) = state_at(&run.path, t, 1.0);
    cut_path(&mut run.path, t);
    let lc = body.state.local_center;
    run.path.push(PathPiece {
        sweep: Sweep::new(lc, c, a, c, a),
        from: t,
        to: 1.0,
    });
    run.impacts.retain(|i| i.fraction <= t);
    let pose = run.path.last().expect("just pushed").sweep.pose_at(0.0);
    run.outcome.position = pose.p;
    run.outcome.angle = a;
    run.outcome.impacts = run.impacts.len() as u32;
    run.outcome.squeezed = false;
    run.outcome.failure = failure.or(run.outcome.failure);
    if body.state.velocity.is_some() {
        run.outcome.velocity = Some(velocity);
    }
}

/// Stops a body at fraction `t` for the rest of the step, keeping `velocity` as its own (when
/// it keeps one): it stands there, unless a moving target strikes it there, which the world's
/// solve of that stand finds (a body stopped among still targets only stands).
fn stand(
    body: &MutualBody,
    run: &mut BodyRun,
    (t, velocity): (f32, (Vec2, f32)),
    (statics, filter): (&StaticSet, &impl BodyFilter),
    settings: &SolveSettings,
) {
    if t >= 1.0 || !statics.has_movers() {
        stop_at(body, run, t, velocity, None);
        return;
    }
    let (c, a, _) = state_at(&run.path, t, settings.dt);
    let state = BodyState {
        sweep: Sweep::new(body.state.local_center, c, a, c, a),
        velocity: Some(velocity),
        ..body.state
    };
    resolve_from(t, (body, filter), &state, run, statics, settings);
}

/// Clamps a body at its bound at fraction `t`: it stands there for the rest of the step, at
/// rest (a velocity kept would only drive it into the same bodies again next step), an
/// infinite mass to the others. A moving target that strikes it there pushes it as it pushes
/// any body (left standing, the mover would sink into it); a clamped body it is pushed into
/// is pushed in turn (see the module's documentation).
fn clamp(
    body: &MutualBody,
    run: &mut BodyRun,
    t: f32,
    world: (&StaticSet, &impl BodyFilter),
    settings: &SolveSettings,
) {
    stand(body, run, (t, (Vec2::ZERO, 0.0)), world, settings);
    run.clamped = true;
}

/// Body `run` struck at fraction `t` by `leader`, both of infinite mass, once pushing it has
/// failed to part them [`MAX_BODY_IMPACTS`] times: it is held where it touches the leader and
/// carried with it, rigidly, for the rest of the step (along the leader's path, [`follow`]),
/// and leaves with the velocity of the leader's points where it ends.
fn hold(body: &MutualBody, run: &mut BodyRun, leader: &BodyRun, t: f32, settings: &SolveSettings) {
    let (c, a, _) = state_at(&run.path, t, settings.dt);
    cut_path(&mut run.path, t);
    let mut held = None;
    for piece in leader.path.iter().filter(|p| p.to > t) {
        let lo = piece.from.max(t);
        let lead = |s: f32| {
            let sweep = sub_sweep(piece, s, s);
            (sweep.c0, sweep.a0)
        };
        let held = *held.get_or_insert_with(|| held_by(lead(lo), (c, a)));
        let (lc, slop) = (body.state.local_center, settings.linear_slop);
        follow(lead, (lo, piece.to), held, lc, slop, &mut run.path);
    }
    let end = run.path.last().expect("a completed path has a piece").sweep;
    let last = leader.path.last().expect("a completed path has a piece");
    let span = (last.to - last.from) * settings.dt;
    let (v, w) = if span > 0.0 {
        let s = &last.sweep;
        (s.linear_motion() / span, s.angular_motion() / span)
    } else {
        (Vec2::ZERO, 0.0)
    };
    run.impacts.retain(|i| i.fraction <= t);
    run.outcome.position = end.pose_at(1.0).p;
    run.outcome.angle = end.a1;
    run.outcome.impacts = run.impacts.len() as u32;
    run.outcome.squeezed = false;
    if body.state.velocity.is_some() {
        run.outcome.velocity = Some((v + w * (end.c1 - last.sweep.c1).perp(), w));
    }
}

/// A candidate pair of an island's loop ([`solve_island`]).
struct IslandPair {
    /// The two bodies' positions in the island, lower first.
    key: (usize, usize),
    /// Their earliest meeting at or after the clock, as last searched.
    meeting: Option<Meeting>,
    /// How many times it was searched again: which [`Due`] entry is current.
    stamp: u32,
    /// Not rejected by the rules.
    live: bool,
}

/// A pair's meeting in the loop's queue, ordered by time, then by the pair (the lower first).
#[derive(Clone, Copy, Debug)]
struct Due {
    fraction: f32,
    key: (usize, usize),
    /// The pair's place in the island's list.
    slot: usize,
    stamp: u32,
}

impl Ord for Due {
    fn cmp(&self, other: &Self) -> Ordering {
        (self.fraction.total_cmp(&other.fraction)).then(self.key.cmp(&other.key))
    }
}

impl PartialOrd for Due {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl PartialEq for Due {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Due {}

/// The time-ordered loop over one island (see the module's documentation), from its candidate
/// pairs (ascending); returns its impacts in time order.
fn solve_island(
    (island, island_pairs): (&[u32], &[(u32, u32)]),
    bodies: &[MutualBody],
    runs: &mut IslandRuns,
    statics: &StaticSet,
    settings: &SolveSettings,
    rules: &impl MutualRules,
) -> Vec<MutualImpact> {
    let slop = settings.linear_slop;
    let mut clock = 0.0f32;
    let mut bounds: Vec<Aabb> = island
        .iter()
        .map(|&i| path_bounds(bodies[i as usize].parts, &runs[i as usize].path))
        .collect();
    let infinite =
        |i: u32, runs: &IslandRuns| bodies[i as usize].immovable || runs[i as usize].clamped;
    let drivable = |i: u32, runs: &IslandRuns| {
        !bodies[i as usize].immovable && runs[i as usize].driven < 2 * MAX_BODY_IMPACTS
    };
    // Two infinite masses neither of which can be driven any more are left to pass.
    let settled = |a: u32, b: u32, runs: &IslandRuns| {
        infinite(a, runs) && infinite(b, runs) && !drivable(a, runs) && !drivable(b, runs)
    };
    // Pairs by position in the island, with their earliest meeting, in the order found;
    // `known` holds every pair ever listed (a rejected one stays, so it is not listed again).
    let mut pairs: Vec<IslandPair> = Vec::new();
    let mut known: HashSet<(usize, usize)> = HashSet::new();
    // Each body's pairs (by their place in `pairs`), by position in the island.
    let mut pairs_of: Vec<Vec<usize>> = vec![Vec::new(); island.len()];
    let list = |key: (usize, usize), pairs: &mut Vec<IslandPair>, of: &mut [Vec<usize>]| {
        of[key.0].push(pairs.len());
        of[key.1].push(pairs.len());
        pairs.push(IslandPair {
            key,
            meeting: None,
            stamp: 0,
            live: true,
        });
    };
    let near = |x: usize, y: usize, bounds: &[Aabb]| {
        let (a, b) = (island[x], island[y]);
        !(bodies[a as usize].immovable && bodies[b as usize].immovable)
            && bounds[x].expanded(slop).overlaps(&bounds[y])
            && rules.meets(a, b)
    };
    let place = |i: u32| island.binary_search(&i).expect("an island's pair is in it");
    for &(a, b) in island_pairs {
        let key = (place(a), place(b));
        known.insert(key);
        list(key, &mut pairs, &mut pairs_of);
    }
    let search = |(x, y): (usize, usize), runs: &IslandRuns, clock: f32| {
        let (a, b) = (island[x] as usize, island[y] as usize);
        let mut overlapped = false;
        let pair = (&bodies[b], &runs[b]);
        let meeting = pair_meeting((&bodies[a], &runs[a]), pair, clock, slop, &mut overlapped);
        (meeting, overlapped)
    };
    // The pairs' meetings, earliest first (ties to the lower pair): an entry is current while
    // its pair is live and has not been searched again since (its stamp).
    let mut due: BinaryHeap<Reverse<Due>> = BinaryHeap::new();
    let push = |due: &mut BinaryHeap<Reverse<Due>>, slot: usize, pair: &IslandPair| {
        if let Some(meeting) = pair.meeting {
            due.push(Reverse(Due {
                fraction: meeting.fraction(),
                key: pair.key,
                slot,
                stamp: pair.stamp,
            }));
        }
    };
    // Bodies that start the step overlapping another are reported so, as against a target.
    for (slot, pair) in pairs.iter_mut().enumerate() {
        let overlapped;
        (pair.meeting, overlapped) = search(pair.key, runs, clock);
        if overlapped {
            for z in [pair.key.0, pair.key.1] {
                runs[island[z] as usize].outcome.started_overlapping = true;
            }
        }
        push(&mut due, slot, pair);
    }
    let mut impacts = Vec::new();
    while let Some(Reverse(next)) = due.pop() {
        let pair = &pairs[next.slot];
        if !pair.live || pair.stamp != next.stamp {
            continue;
        }
        let ((x, y), meeting) = (pair.key, pair.meeting.expect("a due pair has a meeting"));
        let (a, b) = (island[x], island[y]);
        let t = meeting.fraction().max(clock);
        clock = t;
        let (ia, ib) = (a as usize, b as usize);
        match meeting {
            Meeting::Failed { failure, .. } => {
                for i in [ia, ib] {
                    if !bodies[i].immovable {
                        let (_, _, v) = state_at(&runs[i].path, t, settings.dt);
                        stop_at(&bodies[i], &mut runs[i], t, v, Some(failure));
                        runs[i].clamped = true;
                    }
                }
            }
            Meeting::Hit {
                parts: (part_a, part_b),
                contact,
                ..
            } => {
                let at = |i: usize| {
                    let (c, _, (v, w)) = state_at(&runs[i].path, t, settings.dt);
                    v + w * (contact.point - c).perp()
                };
                let hit = MutualHit {
                    parts: (part_a, part_b),
                    fraction: t,
                    point: contact.point,
                    normal: -contact.normal,
                    velocity: at(ia) - at(ib),
                };
                if !rules.accept(a, b, &hit) {
                    // Ignored for the rest of the step, as a rejected target is.
                    pairs[next.slot].live = false;
                    continue;
                }
                // A body past its bound is clamped here, an infinite mass from now on.
                for i in [ia, ib] {
                    if !bodies[i].immovable
                        && !runs[i].clamped
                        && runs[i].mutual >= MAX_BODY_IMPACTS
                    {
                        let world = (statics, &rules.world(i as u32));
                        clamp(&bodies[i], &mut runs[i], t, world, settings);
                    }
                }
                // Two infinite masses: neither gives way by the masses, so the one struck
                // (of two that may be, the one moving the less toward the other) is pushed as
                // a moving target pushes a body.
                let mut pushed = None;
                if infinite(a, runs) && infinite(b, runs) {
                    let toward = |i: usize| {
                        let (c, _, (v, w)) = state_at(&runs[i].path, t, settings.dt);
                        (v + w * (contact.point - c).perp()).dot(hit.normal)
                    };
                    let a_struck = -toward(ia) < toward(ib);
                    pushed = match (drivable(a, runs), drivable(b, runs)) {
                        (true, true) => Some(if a_struck { ia } else { ib }),
                        (true, false) => Some(ia),
                        (false, true) => Some(ib),
                        (false, false) => None,
                    };
                }
                if let Some(i) = pushed {
                    runs[i].driven += 1;
                }
                if let Some(i) = pushed.filter(|&i| runs[i].driven > MAX_BODY_IMPACTS) {
                    let leader = runs[if i == ia { ib } else { ia }].clone();
                    hold(&bodies[i], &mut runs[i], &leader, t, settings);
                    impacts.push(MutualImpact {
                        a,
                        b,
                        part_a,
                        part_b,
                        fraction: t,
                        point: contact.point,
                        normal: hit.normal,
                    });
                } else if pushed.is_some() || !(infinite(a, runs) && infinite(b, runs)) {
                    let impact = respond(
                        (a, b),
                        (part_a, part_b),
                        t,
                        &contact,
                        bodies,
                        runs,
                        (statics, rules, pushed),
                        settings,
                    );
                    impacts.push(impact);
                }
            }
        }
        // The two bodies' pairs, searched again from the clock, and any new pair their new
        // paths make.
        for (z, i) in [(x, a), (y, b)] {
            bounds[z] = path_bounds(bodies[i as usize].parts, &runs[i as usize].path);
        }
        for w in 0..island.len() {
            for z in [x, y] {
                if w == z || (z == y && w == x) {
                    continue;
                }
                let key = (w.min(z), w.max(z));
                if !known.contains(&key) && near(key.0, key.1, &bounds) {
                    known.insert(key);
                    list(key, &mut pairs, &mut pairs_of);
                }
            }
        }
        for z in [x, y] {
            for &slot in &pairs_of[z] {
                let pair = &mut pairs[slot];
                let (p, q) = pair.key;
                // The pair of `x` and `y` is in both lists: searched once.
                if !pair.live || (z == y && (p == x || q == x)) {
                    continue;
                }
                let (u, v) = (island[p], island[q]);
                pair.meeting = if settled(u, v, runs) {
                    None
                } else {
                    search(pair.key, runs, clock).0
                };
                pair.stamp += 1;
                push(&mut due, slot, pair);
            }
        }
    }
    impacts
}

/// The impulse between bodies `a` and `b` meeting at fraction `t`, then each that can be
/// pushed solved on from there (`SubStep`) or stopped there (`Clamp`).
#[allow(clippy::too_many_arguments)]
fn respond(
    (a, b): (u32, u32),
    (part_a, part_b): (u32, u32),
    t: f32,
    contact: &Contact,
    bodies: &[MutualBody],
    runs: &mut IslandRuns,
    (statics, rules, pushed): (&StaticSet, &impl MutualRules, Option<usize>),
    settings: &SolveSettings,
) -> MutualImpact {
    let (ia, ib) = (a as usize, b as usize);
    let slop = settings.linear_slop;
    let (ca, aa, va) = state_at(&runs[ia].path, t, settings.dt);
    let (cb, ab, vb) = state_at(&runs[ib].path, t, settings.dt);
    let (ba, bb) = (&bodies[ia], &bodies[ib]);
    let pose = |c: Vec2, angle: f32, body: &MutualBody| {
        Sweep::new(body.state.local_center, c, angle, c, angle).pose_at(0.0)
    };
    // The middle of the contact patch, where the impulse acts (as against a target).
    let patch = contact.patch.unwrap_or_else(|| {
        contact_patch(
            &ba.parts[part_a as usize].proxy,
            pose(ca, aa, ba),
            &bb.parts[part_b as usize].proxy,
            pose(cb, ab, bb),
            (contact.normal, contact.point),
            slop,
        )
    });
    let point = 0.5 * (patch.0 + patch.1);
    let normal = -contact.normal;
    let mass = |i: usize| {
        let body = &bodies[i];
        let free = !runs[i].clamped || pushed == Some(i);
        (!body.immovable && free).then_some((body.state.mass, body.state.inertia))
    };
    let side_a = Side {
        velocity: va,
        r: point - ca,
        mass: mass(ia),
    };
    let side_b = Side {
        velocity: vb,
        r: point - cb,
        mass: mass(ib),
    };
    let restitution = ba.state.restitution.max(bb.state.restitution);
    let friction = (ba.state.friction * bb.state.friction).max(0.0).sqrt();
    let response = mutual_response(&side_a, &side_b, normal, (restitution, friction));
    for (i, side, new, other) in [
        (ia, side_a, response.map(|r| r.0), ib),
        (ib, side_b, response.map(|r| r.1), ia),
    ] {
        if side.mass.is_none() {
            continue;
        }
        // A clamped body pushed counts toward its own bound of pushes, not this one.
        if pushed != Some(i) {
            runs[i].mutual += 1;
        }
        let body = &bodies[i];
        // An infinite mass (immovable, clamped) may move on after the impact, as a moving
        // target does: a body stopped there would be struck again at once, so it goes on in
        // both modes. A contact the two start the step with does not stop them either, as a
        // contact a body starts the step with a target: they respond and go on.
        let finite = |j: usize| !bodies[j].immovable && (!runs[j].clamped || pushed == Some(j));
        let stop = settings.mode == Resolution::Clamp && finite(other) && t > 0.0;
        match new {
            Err(failure) => stop_at(body, &mut runs[i], t, side.velocity, Some(failure)),
            Ok(velocity) if stop || t >= 1.0 => {
                let world = (statics, &rules.world(i as u32));
                stand(body, &mut runs[i], (t, velocity), world, settings);
            }
            Ok(velocity) => {
                let remaining = (1.0 - t) * settings.dt;
                let c = if i == ia { ca } else { cb };
                let angle = if i == ia { aa } else { ab };
                let state = BodyState {
                    sweep: Sweep::new(
                        body.state.local_center,
                        c,
                        angle,
                        c + velocity.0 * remaining,
                        angle + velocity.1 * remaining,
                    ),
                    velocity: Some(velocity),
                    ..body.state
                };
                let filter = rules.world(i as u32);
                resolve_from(t, (body, &filter), &state, &mut runs[i], statics, settings);
            }
        }
    }
    MutualImpact {
        a,
        b,
        part_a,
        part_b,
        fraction: t,
        point,
        normal,
    }
}

#[cfg(test)]
mod tests {
    //! Bodies meeting bodies, judged by independent `f64` distances (centres for balls,
    //! segments for rods) along the paths the solver reports and at the step's end, not by the
    //! solver's own queries.
    use super::*;
    use crate::geometry::test_support::Rng;
    use crate::geometry::{Capsule, Circle, LINEAR_SLOP, Polygon, Shape};
    use glam::DVec2;

    const DT: f32 = 1.0 / 60.0;

    /// A body of the tests: one collider (a ball, or a rod: a capsule along its x axis).
    #[derive(Clone, Copy, Debug)]
    struct Thing {
        state: BodyState,
        part: BodyPart,
        /// Radius (a ball) or half length and radius (a rod).
        shape: (f32, f32),
        immovable: bool,
    }

    fn thing(shape: Shape, (mass, inertia): (f32, f32), size: (f32, f32)) -> Thing {
        let proxy = shape.proxy();
        Thing {
            state: BodyState {
                local_center: Vec2::ZERO,
                mass,
                inertia,
                restitution: 1.0,
                friction: 0.0,
                sweep: Sweep::default(),
                velocity: Some((Vec2::ZERO, 0.0)),
            },
            part: BodyPart {
                proxy,
                core_center: Vec2::ZERO,
                core_radius: 0.25 * size.1,
            },
            shape: size,
            immovable: false,
        }
    }

    /// A ball of radius `r` and mass `m` (a uniform disc).
    fn ball(r: f32, m: f32) -> Thing {
        let shape = Shape::from(Circle::new(r).unwrap());
        thing(shape, (m, 0.5 * m * r * r), (0.0, r))
    }

    /// A rod of half length `h`, radius `r` and mass `m` (its inertia a thin rod's).
    fn rod(h: f32, r: f32, m: f32) -> Thing {
        let shape = Shape::from(Capsule::horizontal(h, r).unwrap());
        thing(shape, (m, m * (2.0 * h) * (2.0 * h) / 12.0), (h, r))
    }

    /// `thing` at `position` and `angle`, moving with `(v, w)` over the next step.
    fn placed(mut thing: Thing, position: Vec2, angle: f32, (v, w): (Vec2, f32)) -> Thing {
        thing.state.sweep = Sweep::new(
            Vec2::ZERO,
            position,
            angle,
            position + v * DT,
            angle + w * DT,
        );
        thing.state.velocity = Some((v, w));
        thing
    }

    fn settings(mode: Resolution) -> SolveSettings {
        SolveSettings {
            mode,
            linear_slop: LINEAR_SLOP,
            dt: DT,
        }
    }

    /// Solves one step of `things` (no world) and moves each to where it ended, with its new
    /// velocity for the next.
    fn step(things: &mut [Thing], mode: Resolution) -> BodiesOutcome {
        step_in(things, &StaticSet::default(), mode)
    }

    /// [`step`] in a world of `statics`.
    fn step_in(things: &mut [Thing], statics: &StaticSet, mode: Resolution) -> BodiesOutcome {
        let parts: Vec<[BodyPart; 1]> = things.iter().map(|t| [t.part]).collect();
        let bodies: Vec<MutualBody> = things
            .iter()
            .zip(&parts)
            .map(|(t, p)| MutualBody {
                state: t.state,
                parts: p,
                immovable: t.immovable,
            })
            .collect();
        let out = solve_bodies(&bodies, statics, &settings(mode), &|_, _| true);
        for (thing, run) in things.iter_mut().zip(&out.runs) {
            let o = &run.outcome;
            let velocity = o.velocity.unwrap();
            *thing = placed(*thing, o.position, o.angle, velocity);
        }
        out
    }

    /// The centre and angle of a path at fraction `t`, in `f64`.
    fn pose_on(path: &[PathPiece], t: f32) -> (DVec2, f64) {
        let piece = path
            .iter()
            .find(|p| p.from <= t && t <= p.to)
            .expect("the path covers the step");
        let s = sub_sweep(piece, t, piece.to);
        (s.c0.as_dvec2(), f64::from(s.a0))
    }

    /// The distance of two points to segment `[p, q]`.
    fn point_segment(x: DVec2, p: DVec2, q: DVec2) -> f64 {
        let d = q - p;
        let u = if d.length_squared() > 0.0 {
            ((x - p).dot(d) / d.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        x.distance(p + u * d)
    }

    /// The surface distance of two things at the given centres and angles (negative when they
    /// overlap): centres for balls, segment to segment for rods (the least of the four
    /// end-to-segment distances when the segments do not cross).
    fn distance(a: &Thing, (ca, aa): (DVec2, f64), b: &Thing, (cb, ab): (DVec2, f64)) -> f64 {
        let ends = |c: DVec2, angle: f64, h: f32| {
            let along = DVec2::from_angle(angle) * f64::from(h);
            (c - along, c + along)
        };
        let (a0, a1) = ends(ca, aa, a.shape.0);
        let (b0, b1) = ends(cb, ab, b.shape.0);
        // Segments that cross are as deep in each other as can be: a metre, say.
        let side = |p: DVec2, q: DVec2, x: DVec2| (q - p).perp_dot(x - p);
        let crossing =
            side(a0, a1, b0) * side(a0, a1, b1) < 0.0 && side(b0, b1, a0) * side(b0, b1, a1) < 0.0;
        if crossing {
            return -1.0;
        }
        let core = point_segment(a0, b0, b1)
            .min(point_segment(a1, b0, b1))
            .min(point_segment(b0, a0, a1))
            .min(point_segment(b1, a0, a1));
        core - f64::from(a.shape.1 + b.shape.1)
    }

    /// The least distance of `a` and `b` along their paths over the step, at `samples` times
    /// and at every piece boundary.
    fn closest(a: (&Thing, &BodyRun), b: (&Thing, &BodyRun), samples: u32) -> f64 {
        let mut times: Vec<f32> = (0..=samples).map(|k| k as f32 / samples as f32).collect();
        times.extend(
            a.1.path
                .iter()
                .chain(&b.1.path)
                .flat_map(|p| [p.from, p.to]),
        );
        times
            .iter()
            .map(|&t| distance(a.0, pose_on(&a.1.path, t), b.0, pose_on(&b.1.path, t)))
            .fold(f64::INFINITY, f64::min)
    }

    /// Momentum and twice the kinetic energy (rotation included) of `things`, in `f64`.
    fn totals(things: &[Thing]) -> (DVec2, f64, f64) {
        things
            .iter()
            .fold((DVec2::ZERO, 0.0, 0.0), |(p, scale, e), t| {
                let (v, w) = t.state.velocity.unwrap();
                let (m, i) = (f64::from(t.state.mass), f64::from(t.state.inertia));
                let v = v.as_dvec2();
                let w = f64::from(w);
                (
                    p + m * v,
                    scale + m * v.length(),
                    e + m * v.length_squared() + i * w * w,
                )
            })
    }

    const MODES: [Resolution; 2] = [Resolution::Clamp, Resolution::SubStep { max_substeps: 4 }];

    /// Two balls and two rods (1 m long, 1 cm thick, spinning 5 turns a second, meeting off
    /// centre), head-on at 2,000 m/s each with restitution 1, in both modes: they meet, bounce
    /// and never pass (along their paths and at every step's end, by the `f64` distance), and
    /// keep their momentum and kinetic energy (rotation included) within 1e-4 relative: the
    /// impulse keeps both exactly but for the rounding of the `f32` velocities and of the
    /// velocities read back from the swept poses (a few ulps of 2,000 m/s).
    #[test]
    fn head_on_pairs_at_2000_m_s_bounce_and_never_pass() {
        let spin = 5.0 * core::f32::consts::TAU;
        let pairs = [
            (
                placed(
                    ball(0.1, 1.0),
                    Vec2::new(-40.0, 0.0),
                    0.0,
                    (Vec2::new(2000.0, 0.0), 0.0),
                ),
                placed(
                    ball(0.1, 1.0),
                    Vec2::new(40.0, 0.03),
                    0.0,
                    (Vec2::new(-2000.0, 0.0), 0.0),
                ),
            ),
            (
                placed(
                    rod(0.5, 0.005, 0.5),
                    Vec2::new(-40.0, 0.0),
                    1.0,
                    (Vec2::new(2000.0, 0.0), spin),
                ),
                placed(
                    rod(0.5, 0.005, 0.5),
                    Vec2::new(40.0, 0.2),
                    0.0,
                    (Vec2::new(-2000.0, 0.0), -spin),
                ),
            ),
        ];
        for mode in MODES {
            for (kind, &(a, b)) in ["balls", "rods"].iter().zip(&pairs) {
                let mut things = [a, b];
                let (p0, scale, e0) = totals(&things);
                let mut met = 0;
                for _ in 0..4 {
                    let before = things;
                    let out = step(&mut things, mode);
                    met += out.impacts.len();
                    let gap = closest((&before[0], &out.runs[0]), (&before[1], &out.runs[1]), 4000);
                    assert!(
                        gap >= -f64::from(LINEAR_SLOP),
                        "{kind} {mode:?}: {gap} m apart"
                    );
                    assert!(
                        things[0].state.sweep.c0.x < things[1].state.sweep.c0.x,
                        "{kind} {mode:?}: passed"
                    );
                }
                assert!(met >= 1, "{kind} {mode:?}: never met");
                let (p1, _, e1) = totals(&things);
                assert!(
                    (p1 - p0).length() <= 1e-4 * scale,
                    "{kind} {mode:?}: {p0} -> {p1}"
                );
                assert!(
                    (e1 - e0).abs() <= 1e-4 * e0,
                    "{kind} {mode:?}: {e0} -> {e1}"
                );
                // Bounced: each leaves the way it came.
                let v = |k: usize| things[k].state.velocity.unwrap().0.x;
                assert!(
                    v(0) < 0.0 && v(1) > 0.0,
                    "{kind} {mode:?}: {} {}",
                    v(0),
                    v(1)
                );
            }
        }
    }

    /// Newton's cradle: four balls in a row a slop apart, a fifth striking the first at 10 m/s
    /// (restitution 1, no friction) in `SubStep`: the impulse passes ball to ball at the same
    /// instant, and the last leaves at 10 m/s while the others stand still.
    #[test]
    fn newtons_cradle_passes_the_impulse_to_the_last_ball() {
        let r = 0.1f32;
        let gap = 2.0 * r + LINEAR_SLOP;
        let mut things: Vec<Thing> = (0..5)
            .map(|k| {
                let (x, v) = if k == 0 {
                    (-gap - 0.1, 10.0)
                } else {
                    ((k - 1) as f32 * gap, 0.0)
                };
                placed(
                    ball(r, 1.0),
                    Vec2::new(x, 0.0),
                    0.0,
                    (Vec2::new(v, 0.0), 0.0),
                )
            })
            .collect();
        let out = step(&mut things, Resolution::SubStep { max_substeps: 4 });
        let v: Vec<f32> = things
            .iter()
            .map(|t| t.state.velocity.unwrap().0.x)
            .collect();
        assert_eq!(out.impacts.len(), 4, "{:?} {v:?}", out.impacts);
        assert!((v[4] - 10.0).abs() < 1e-3, "{v:?}");
        assert!(v[..4].iter().all(|v| v.abs() < 1e-3), "{v:?}");
        assert!(
            things[4].state.sweep.c0.x > 3.0 * gap + 0.05,
            "{:?}",
            things[4].state.sweep
        );
        assert_eq!(out.clamped, 0);
    }

    /// A bullet (5 cm, 5 kg) at 2,000 m/s into a crowd of 1,000 balls (10 cm, 1 kg) drifting at
    /// up to 1 m/s, a grid of 50 × 20 half a metre apart, over three steps in both modes: by the
    /// `f64` distance of centres along every path the solver reports (4,000 samples a step and
    /// every piece boundary), no body passes into another deeper than the slop, and none ends a
    /// step so.
    #[test]
    fn a_bullet_at_2000_m_s_never_passes_through_a_crowd() {
        let mut rng = Rng(32);
        let mut crowd = vec![placed(
            ball(0.05, 5.0),
            Vec2::new(-5.0, 0.03),
            0.0,
            (Vec2::new(2000.0, 0.0), 0.0),
        )];
        for i in 0..50 {
            for j in 0..20 {
                let at = Vec2::new(1.0 + 0.5 * i as f32, -5.0 + 0.5 * j as f32);
                let v = Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                crowd.push(placed(ball(0.1, 1.0), at, 0.0, (v, rng.range(-3.0, 3.0))));
            }
        }
        for mode in MODES {
            let mut things = crowd.clone();
            let mut hits = 0;
            for _ in 0..3 {
                let before = things.clone();
                let out = step(&mut things, mode);
                hits += out.impacts.iter().filter(|i| i.a == 0).count();
                let bullet = (&before[0], &out.runs[0]);
                for (k, other) in before.iter().zip(&out.runs).enumerate().skip(1) {
                    let gap = closest(bullet, other, 4000);
                    assert!(
                        gap >= -f64::from(LINEAR_SLOP),
                        "{mode:?}: bullet {gap} m into {k}"
                    );
                }
                for a in 0..things.len() {
                    for b in a + 1..things.len() {
                        let at = |t: &Thing| (t.state.sweep.c0.as_dvec2(), 0.0);
                        let d = distance(&things[a], at(&things[a]), &things[b], at(&things[b]));
                        assert!(d >= -f64::from(LINEAR_SLOP), "{mode:?}: {a} {d} m into {b}");
                    }
                }
            }
            assert!(hits >= 1, "{mode:?}: the bullet hit nothing");
        }
    }

    /// A third ball far from the others: its step must be what it is alone, to the bit.
    fn bystander() -> Thing {
        placed(
            ball(0.1, 1.0),
            Vec2::new(0.0, 50.0),
            0.0,
            (Vec2::new(30.0, -7.0), 2.0),
        )
    }

    /// The bystander's outcome alone.
    fn alone_outcome(mode: Resolution) -> BodyOutcome {
        let mut only = [bystander()];
        step(&mut only, mode).runs[0].outcome
    }

    /// Two balls spawned overlapping by half their radius, one drifting into the other at
    /// 1 m/s: both are reported as starting overlapped, and over 20 steps neither is launched
    /// (no speed above the 1 m/s they started with, every number finite); a ball far away is
    /// unaffected.
    #[test]
    fn bodies_spawned_overlapping_are_reported_and_not_launched() {
        for mode in MODES {
            let mut things = [
                placed(ball(0.1, 1.0), Vec2::ZERO, 0.0, (Vec2::new(1.0, 0.0), 0.0)),
                placed(
                    ball(0.1, 1.0),
                    Vec2::new(0.15, 0.01),
                    0.0,
                    (Vec2::ZERO, 0.0),
                ),
                bystander(),
            ];
            let first = step(&mut things, mode);
            let o = |k: usize| first.runs[k].outcome;
            assert!(
                o(0).started_overlapping && o(1).started_overlapping,
                "{mode:?}"
            );
            assert_eq!(o(2), alone_outcome(mode), "{mode:?}");
            for _ in 0..19 {
                step(&mut things, mode);
            }
            for t in &things[..2] {
                let (v, w) = t.state.velocity.unwrap();
                assert!(
                    t.state.sweep.is_finite() && w.is_finite(),
                    "{mode:?}: {t:?}"
                );
                assert!(v.length() <= 1.0 + 1e-4, "{mode:?}: launched at {v}");
            }
        }
    }

    /// A ball of zero mass struck by another: the impulse has no answer, so both stop where
    /// they meet with `InvalidInput`, short of each other, and a ball far away is unaffected.
    /// A subnormal mass is a feather, not an error: it bounces off and the heavy ball goes on
    /// almost as before. A ball with a NaN velocity harms no other body: theirs are what they
    /// are without it.
    #[test]
    fn a_bad_mass_or_velocity_in_a_pair_stays_with_its_pair() {
        let striker = placed(
            ball(0.1, 1.0),
            Vec2::new(-0.5, 0.0),
            0.0,
            (Vec2::new(60.0, 0.0), 0.0),
        );
        for mode in MODES {
            let mut zero = placed(ball(0.1, 1.0), Vec2::new(0.5, 0.0), 0.0, (Vec2::ZERO, 0.0));
            zero.state.mass = 0.0;
            zero.state.inertia = 0.0;
            let mut things = [striker, zero, bystander()];
            let out = step(&mut things, mode);
            for k in 0..2 {
                let o = out.runs[k].outcome;
                assert_eq!(
                    o.failure,
                    Some(ToiFailure::InvalidInput),
                    "{mode:?}: {k} {o:?}"
                );
            }
            let (a, b) = (things[0].state.sweep.c0, things[1].state.sweep.c0);
            assert!(
                a.x > -0.5 && a.x < b.x - 0.2 && b.x == 0.5,
                "{mode:?}: {a} {b}"
            );
            assert_eq!(out.runs[2].outcome, alone_outcome(mode), "{mode:?}");

            let mut feather = placed(ball(0.1, 1.0), Vec2::new(0.5, 0.0), 0.0, (Vec2::ZERO, 0.0));
            feather.state.mass = f32::from_bits(1);
            feather.state.inertia = f32::from_bits(1);
            let mut things = [striker, feather];
            let out = step(&mut things, mode);
            assert_eq!(out.impacts.len(), 1, "{mode:?}");
            assert!(
                out.runs.iter().all(|r| r.outcome.failure.is_none()),
                "{mode:?}"
            );
            let (v, _) = things[0].state.velocity.unwrap();
            assert!((v.x - 60.0).abs() < 1e-3, "{mode:?}: {v}");
            assert!(things[1].state.sweep.is_finite(), "{mode:?}");

            let mut broken = placed(ball(0.1, 1.0), Vec2::new(0.5, 0.0), 0.0, (Vec2::ZERO, 0.0));
            broken.state.sweep.c1 = Vec2::NAN;
            broken.state.velocity = Some((Vec2::NAN, 0.0));
            let mut things = [striker, broken, bystander()];
            let out = step(&mut things, mode);
            let mut only = [striker];
            assert_eq!(
                out.runs[0].outcome,
                step(&mut only, mode).runs[0].outcome,
                "{mode:?}"
            );
            assert_eq!(out.runs[2].outcome, alone_outcome(mode), "{mode:?}");
        }
    }

    /// An immovable rod sliding at -10 m/s is struck by a ball at 100 m/s (restitution 1): the
    /// ball leaves at -120 m/s (its approach reversed relative to the rod), and the rod is not
    /// pushed: its step is what it is alone, to the bit.
    #[test]
    fn an_immovable_body_is_never_pushed() {
        for mode in MODES {
            let mut wall = rod(1.0, 0.05, 1.0);
            wall.immovable = true;
            let wall = placed(
                wall,
                Vec2::new(1.0, 0.0),
                core::f32::consts::FRAC_PI_2,
                (Vec2::new(-10.0, 0.0), 0.0),
            );
            let ball = placed(
                ball(0.1, 1.0),
                Vec2::ZERO,
                0.0,
                (Vec2::new(100.0, 0.0), 0.0),
            );
            let mut things = [ball, wall];
            let out = step(&mut things, mode);
            assert_eq!(out.impacts.len(), 1, "{mode:?}");
            let (v, _) = things[0].state.velocity.unwrap();
            assert!((v.x + 120.0).abs() < 1e-2, "{mode:?}: {v}");
            let mut only = [wall];
            assert_eq!(
                out.runs[1].outcome,
                step(&mut only, mode).runs[0].outcome,
                "{mode:?}"
            );
        }
    }

    /// A ball between two immovable slabs closing on it at 20 m/s each bounces between them
    /// ever faster (sub-steps) or is struck again and again where it stopped (clamp); after
    /// `MAX_BODY_IMPACTS` impacts it is clamped and counted, then pushed and held by the slabs
    /// to its bound of those (a true squeeze: nothing can keep it out of both), and the step
    /// ends.
    #[test]
    fn a_body_past_its_bound_is_clamped_and_counted() {
        let slab = |x: f32, v: f32| {
            let shape = Shape::from(Polygon::rectangle(0.05, 1.0).unwrap());
            let mut slab = thing(shape, (1.0, 1.0), (0.0, 0.0));
            slab.immovable = true;
            placed(slab, Vec2::new(x, 0.0), 0.0, (Vec2::new(v, 0.0), 0.0))
        };
        for mode in MODES {
            let ball = placed(ball(0.1, 1.0), Vec2::ZERO, 0.0, (Vec2::new(5.0, 0.0), 0.0));
            let mut things = [slab(-0.4, 20.0), ball, slab(0.4, -20.0)];
            let out = step(&mut things, mode);
            let run = &out.runs[1];
            assert!(run.clamped && out.clamped == 1, "{mode:?}: {run:?}");
            assert_eq!(run.mutual, MAX_BODY_IMPACTS, "{mode:?}: {run:?}");
            assert_eq!(run.driven, 2 * MAX_BODY_IMPACTS, "{mode:?}: {run:?}");
            assert!(things[1].state.sweep.is_finite());
        }
    }

    /// A closed box 20 m across (walls 10 cm thick, inner faces at ±10 m) and 196 bodies in
    /// it, one to a cell of 1.4 m: balls of 5–30 cm and rods 1 cm thick and 10 cm to 1 m long,
    /// at up to 2,000 m/s and 60 turns a second, restitution 0–1, over 60 steps in both modes.
    /// By `f64` distances at every step's end: no body leaves the box, no two bodies overlap
    /// deeper than the slop, and none is left in a failed state.
    #[test]
    fn a_crowded_box_at_2000_m_s_keeps_bodies_apart_and_inside() {
        let wall = |x: f32, y: f32, hw: f32, hh: f32| StaticItem {
            proxy: Shape::from(Polygon::rectangle(hw, hh).unwrap()).proxy(),
            position: Vec2::new(x, y),
            angle: 0.0,
        };
        let mut statics = StaticSet::default();
        statics.rebuild([
            wall(0.0, -10.05, 10.1, 0.05),
            wall(0.0, 10.05, 10.1, 0.05),
            wall(-10.05, 0.0, 0.05, 10.1),
            wall(10.05, 0.0, 0.05, 10.1),
        ]);
        let mut rng = Rng(3200);
        let mut crowd = Vec::new();
        for i in 0..14 {
            for j in 0..14 {
                let at = Vec2::new(-9.1 + 1.4 * i as f32, -9.1 + 1.4 * j as f32);
                let mut t = if (i + j) % 2 == 0 {
                    let r = rng.range(0.05, 0.3);
                    ball(r, 3.0 * r * r)
                } else {
                    let h = rng.range(0.05, 0.5);
                    rod(h, 0.005, 0.02 * h)
                };
                t.state.restitution = rng.next();
                t.state.friction = 0.3 * rng.next();
                let speed = 2000.0 * rng.next() * rng.next();
                let v = Vec2::from_angle(rng.range(0.0, 6.3)) * speed;
                let w = rng.range(-1.0, 1.0) * 60.0 * core::f32::consts::TAU;
                crowd.push(placed(t, at, rng.range(0.0, 6.3), (v, w)));
            }
        }
        let slop = f64::from(LINEAR_SLOP);
        for mode in MODES {
            let mut things = crowd.clone();
            for s in 0..60 {
                let out = step_in(&mut things, &statics, mode);
                for (k, (t, run)) in things.iter().zip(&out.runs).enumerate() {
                    assert_eq!(run.outcome.failure, None, "{mode:?} step {s}: {k}");
                    let (c, a) = (t.state.sweep.c0.as_dvec2(), f64::from(t.state.sweep.a0));
                    let along = DVec2::from_angle(a) * f64::from(t.shape.0);
                    for end in [c - along, c + along] {
                        let out = end.abs().max_element() + f64::from(t.shape.1) - 10.0;
                        assert!(out <= slop, "{mode:?} step {s}: {k} {out} m into a wall");
                    }
                }
                let at = |t: &Thing| (t.state.sweep.c0.as_dvec2(), f64::from(t.state.sweep.a0));
                for a in 0..things.len() {
                    for b in a + 1..things.len() {
                        let d = distance(&things[a], at(&things[a]), &things[b], at(&things[b]));
                        assert!(d >= -slop, "{mode:?} step {s}: {a} {d} m into {b}");
                    }
                }
            }
        }
    }
}
