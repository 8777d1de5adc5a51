//! [`CcdConfig`], the plugin's settings.

use bevy_ecs::prelude::*;
use bevy_reflect::prelude::*;

use bevy_reflect::impl_reflect;

use crate::geometry::{LINEAR_SLOP, Resolution};

// `Resolution` is the geometry layer's (which has no Bevy imports): reflected here.
impl_reflect!(
    #[reflect(Debug, Clone, PartialEq, Default)]
    #[type_path = "bevy_ccd::geometry"]
    enum Resolution {
        Clamp,
        SubStep { max_substeps: u32 },
    }
);

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
    /// Bodies collide with each other, ordered in time, as with static and moving targets
    /// (Box2D v2.4's `SolveTOI`): two bodies' paths are swept against each other, the
    /// earliest impact in a group of bodies whose paths meet is resolved first (an impulse
    /// between their two masses), and the two are swept on from there. [`CollisionLayers`]
    /// decide which bodies meet, [`CcdHooks`] see each impact (the other body as the target),
    /// an [`Immovable`] body is never pushed. A body takes at most
    /// [`MAX_BODY_IMPACTS`](crate::geometry::MAX_BODY_IMPACTS) impacts with others in a step,
    /// then stays where it is for the rest of the step
    /// ([`CcdDiagnostics::bodies_clamped`](super::CcdDiagnostics::bodies_clamped) counts them).
    /// The default is `false`: bodies pass through each other, at no cost.
    ///
    /// [`CollisionLayers`]: super::CollisionLayers
    /// [`CcdHooks`]: super::CcdHooks
    /// [`Immovable`]: super::Immovable
    pub bodies_collide: bool,
}

impl Default for CcdConfig {
    fn default() -> Self {
        Self {
            resolution: Resolution::default(),
            linear_slop: LINEAR_SLOP,
            timestep: None,
            parallel: true,
            bodies_collide: false,
        }
    }
}
