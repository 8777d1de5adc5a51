//! A generated level through the plugin, checked against the geometry layer
//! ([`check_level_against_geometry`]): every body's outcome after one step equals
//! `solve_body` called directly on the same inputs, on one thread and on the default pool.
//! The level reads and changes nothing else, so any difference from the direct call is a
//! fault of the plugin's passes (listing, candidate lists, batching, write-back).

use bevy_ccd::prelude::Resolution;
use bevy_ccd::testing::{check_level_against_geometry, check_record_passes};

#[test]
fn level_steps_match_the_geometry_layer_clamp() {
    check_level_against_geometry(Resolution::Clamp);
}

#[test]
fn level_steps_match_the_geometry_layer_substep() {
    check_level_against_geometry(Resolution::SubStep { max_substeps: 4 });
}

#[test]
fn record_passes_on_the_pool_match_one_thread() {
    check_record_passes();
}
