//! A generated level through the plugin, every body at once against each body alone
//! ([`check_level_steps`]): every body's outcome after one step equals its outcome when it is
//! the only body swept, on one thread and on the default pool. The level reads and changes
//! nothing else, so any difference is a fault of the plugin's passes over many bodies
//! (listing, grouped broad-phase queries, lanes, write-back).

mod support;

use bevy_ccd::prelude::Resolution;
use support::level_check::{check_level_steps, check_record_passes};

#[test]
fn level_steps_match_each_body_alone_clamp() {
    check_level_steps(Resolution::Clamp);
}

#[test]
fn level_steps_match_each_body_alone_substep() {
    check_level_steps(Resolution::SubStep { max_substeps: 4 });
}

#[test]
fn record_passes_on_the_pool_match_one_thread() {
    check_record_passes();
}
