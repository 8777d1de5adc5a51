//! [`CcdConfig`], the plugin's settings, and its [`Resolution`].

use bevy_ecs::prelude::*;
use bevy_reflect::prelude::*;

use crate::geometry::LINEAR_SLOP;

/// How bodies are resolved at an impact.
#[derive(Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Debug, Clone, PartialEq)]
pub enum Resolution {
    /// At an impact with a target the body did not start the step touching, its pose becomes
    /// its pose at the impact (at the target separation) and the rest of the step's motion is
    /// dropped; its velocity (if it keeps a [`Velocity`](super::Velocity)) still gets the impact response. The
    /// contacts a body starts the step with (resting, sliding) get the response and the step
    /// goes on, as in `SubStep`. A ball bouncing between walls travels 59 % of the sub-stepped
    /// distance: use `SubStep` for bouncing.
    Clamp,
    /// Advance to the impact, respond with an impulse (restitution, friction, mass and
    /// inertia), spend the remaining fraction of the step from there with a new sweep, search
    /// again; after `max_substeps` impacts, clamp.
    SubStep {
        /// The most impacts handled in one step after the first; contacts resolved without
        /// advancing count too. The default is 4; values above
        /// [`MAX_SUBSTEPS`](crate::geometry::constants::MAX_SUBSTEPS) (64) are capped there,
        /// with one warning.
        max_substeps: u32,
    },
}

impl Default for Resolution {
    fn default() -> Self {
        Self::SubStep { max_substeps: 4 }
    }
}

/// Settings of the plugin.
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
///
/// let mut app = App::new();
/// app.add_plugins((bevy_time::TimePlugin, CcdPlugin::default()))
///     .insert_resource(CcdConfig { resolution: Resolution::Clamp, ..Default::default() });
/// ```
#[derive(Resource, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Resource, Debug, Clone, PartialEq)]
pub struct CcdConfig {
    /// Clamp or sub-step. The default is sub-stepping with up to 4 sub-steps.
    pub resolution: Resolution,
    /// Linear slop (m): the gap left at an impact and the scale of every tolerance. The
    /// default is [`LINEAR_SLOP`] (0.005 m); scale it with your length unit. It also sets
    /// the coordinate limit, [`max_world_coordinate`](crate::geometry::max_world_coordinate)
    /// (1,024 m at the default).
    pub linear_slop: f32,
    /// Length of a step (s) used to turn displacements into velocities. The default is
    /// `None`: the fixed timestep of `Time<Fixed>`.
    pub timestep: Option<f32>,
    /// Spread bodies over the compute task pool. Results are identical either way. The default
    /// is `true`.
    ///
    /// The thread that runs the plugin's schedules (the main thread in an app) works beside
    /// the pool's threads, so a pool of one thread already makes two workers: Bevy's default
    /// pools give a 2-core machine exactly that (one thread each for IO and async compute,
    /// the compute pool what is left). A pool as large as the machine has cores makes one
    /// worker more than there are cores.
    pub parallel: bool,
}

impl Default for CcdConfig {
    fn default() -> Self {
        Self {
            resolution: Resolution::default(),
            linear_slop: LINEAR_SLOP,
            timestep: None,
            parallel: true,
        }
    }
}
