//! The level checks of `tests/level.rs` with a compute task pool of one thread, as Bevy's
//! default pools give a 2-core machine: the thread that runs the plugin's schedules and the
//! pool's one thread share every parallel region (two workers), and the answers must still
//! equal the serial ones and each body's alone, bit for bit.

mod support;

use bevy_ccd::prelude::Resolution;
use bevy_tasks::{ComputeTaskPool, TaskPoolBuilder};
use support::level_check::{check_level_steps, check_record_passes};

#[test]
fn level_steps_match_with_a_pool_of_one_thread() {
    // The only test of this binary, so the pool is this one.
    let pool = ComputeTaskPool::get_or_init(|| TaskPoolBuilder::new().num_threads(1).build());
    assert_eq!(pool.thread_num(), 1);
    check_level_steps(Resolution::Clamp);
    check_level_steps(Resolution::SubStep { max_substeps: 4 });
    check_record_passes();
}
