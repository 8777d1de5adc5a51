//! Results are bit-identical between runs, and between one thread and two: every pose, outcome
//! and impact message of the arena after 200 steps.

mod support;

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use bevy_ccd::prelude::*;
use support::app::*;

/// Poses after 200 steps, with the outcome components and every impact message of the run.
type ArenaRun = (Vec<[u32; 7]>, Vec<CcdOutcome>, Vec<CcdImpact>, u64);

fn arena_poses(parallel: bool) -> ArenaRun {
    let config = CcdConfig {
        parallel,
        ..Default::default()
    };
    let (mut app, arena) = logged_arena(1000, config, 1);
    for _ in 0..200 {
        step(&mut app);
    }
    let messages = app
        .world()
        .resource::<Log>()
        .impacts
        .iter()
        .map(|(_, m)| *m)
        .collect();
    let poses = poses(&app, &arena.bodies);
    let outcomes = arena.bodies.iter().map(|e| toi(&app, *e)).collect();
    let mut hasher = DefaultHasher::new();
    poses.hash(&mut hasher);
    (poses, outcomes, messages, hasher.finish())
}

#[test]
fn results_are_identical_across_runs_and_thread_counts() {
    let pool = bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    eprintln!("compute task pool: {} threads", pool.thread_num());
    let (first, first_toi, first_msgs, first_hash) = arena_poses(true);
    let (second, second_toi, second_msgs, second_hash) = arena_poses(true);
    let (serial, serial_toi, serial_msgs, serial_hash) = arena_poses(false);
    eprintln!("pose hashes: {first_hash:016x} {second_hash:016x} {serial_hash:016x} (serial)");
    eprintln!("impact messages: {}", first_msgs.len());
    assert!(first == second, "two parallel runs differ");
    assert!(first == serial, "parallel and serial runs differ");
    assert!(
        !first_msgs.is_empty(),
        "the arena produced no impacts to compare"
    );
    assert!(
        first_toi == second_toi && first_toi == serial_toi,
        "outcomes differ"
    );
    assert!(
        first_msgs == second_msgs,
        "two parallel runs' messages differ"
    );
    assert!(
        first_msgs == serial_msgs,
        "parallel and serial messages differ"
    );
}
