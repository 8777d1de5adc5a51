//! # bevy_ccd
//!
//! Continuous collision detection for Bevy: fast bodies never tunnel through the world.
#![warn(missing_docs)]

pub mod geometry;
