//! The plugin's memory per CCD body, its components plus the workspace's buffers, stays within
//! the budget, serially and on lanes.

mod support;

use bevy_ccd::plugin::StepPoses;
use bevy_ccd::prelude::*;
use support::app::*;

/// The plugin's memory per CCD body (its components plus the workspace's buffers, the
/// collider excluded) stays within the 256-byte budget of issue 4, serially and on lanes.
/// Sizes and capacities are exact, so unlike a speed target this one can live in a test; the
/// scene benchmark reports the same figure at 1k to 50k bodies.
#[test]
fn memory_kept_per_body_is_within_budget() {
    let pool = bevy_tasks::ComputeTaskPool::get_or_init(|| {
        bevy_tasks::TaskPoolBuilder::new().num_threads(2).build()
    });
    eprintln!("compute task pool: {} threads", pool.thread_num());
    for parallel in [false, true] {
        let config = CcdConfig {
            parallel,
            ..Default::default()
        };
        let (mut app, arena) = logged_arena(2000, config, 3);
        for _ in 0..100 {
            step(&mut app);
        }
        let diagnostics = app.world().resource::<CcdDiagnostics>();
        assert_eq!(diagnostics.bodies, arena.bodies.len(), "every body swept");
        let components = size_of::<StepPoses>() + size_of::<CcdOutcome>() + size_of::<CcdEnabled>();
        let total = components + diagnostics.bytes_per_body;
        eprintln!(
            "parallel {parallel}: components {components} B + buffers {} B = {total} B per body",
            diagnostics.bytes_per_body
        );
        assert!(total <= 256, "{total} B per body, budget 256 B");
    }
}
