//! A generated level through the plugin, checked against the geometry layer: every body's
//! outcome after one step equals `solve_body` called directly on the same inputs (the
//! `Sweep` the plugin recorded, the collider, and the static set it swept against), on one
//! thread and on two.
//!
//! The level has 5,000 statics, above the size from which the solve touches the targets'
//! records ahead of the pair tests (`TOUCH_MIN_TARGETS`, 4,096), so that path runs here; the
//! other tests use small worlds. It reads and changes nothing, so any difference from the
//! direct call is a fault of the plugin's passes (gather, candidate lists, batching, write-back).

mod support;

use bevy_ccd::prelude::Resolution;

#[test]
fn level_steps_match_the_geometry_layer_clamp() {
    support::level::check(Resolution::Clamp);
}

#[test]
fn level_steps_match_the_geometry_layer_substep() {
    support::level::check(Resolution::SubStep { max_substeps: 4 });
}

#[test]
fn record_passes_on_the_pool_match_one_thread() {
    support::level::check_records();
}
