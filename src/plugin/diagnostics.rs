//! [`CcdDiagnostics`]: counts a user may read to see what the plugin did in the last step.

use bevy_ecs::prelude::*;
use bevy_reflect::prelude::*;

/// What the last step did, for diagnostics and memory reports; written by the plugin, read by
/// the user.
///
/// `statics` and `static_rebuilds` are current from [`CcdStepSystems::UpdateStatics`] on, the
/// others from [`CcdStepSystems::Solve`] on.
///
/// [`CcdStepSystems::UpdateStatics`]: super::CcdStepSystems::UpdateStatics
/// [`CcdStepSystems::Solve`]: super::CcdStepSystems::Solve
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
///
/// let mut app = App::new();
/// app.add_plugins((bevy_time::TimePlugin, CcdPlugin::default()));
/// let diagnostics = app.world().resource::<CcdDiagnostics>();
/// assert_eq!(diagnostics.bodies, 0);
/// ```
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Default, Debug, Clone, PartialEq)]
pub struct CcdDiagnostics {
    /// Bodies swept in the last step. The default is 0.
    pub bodies: usize,
    /// Static targets in the hierarchy. The default is 0.
    pub statics: usize,
    /// Times the static hierarchy was built: once at the first step, then once per step in
    /// which a static was added, removed, moved or reshaped. The default is 0.
    pub static_rebuilds: u64,
    /// Bytes the plugin's buffers hold per swept body (their capacity divided by the body
    /// count), components not included. The default is 0.
    pub bytes_per_body: usize,
    /// Impacts reported in the last step ([`CcdImpact`](super::CcdImpact) messages). The
    /// default is 0.
    pub impacts: usize,
    /// Bodies that reached the bound of impacts with other bodies in the last step
    /// ([`MAX_BODY_IMPACTS`](crate::geometry::MAX_BODY_IMPACTS)) and were stopped for the rest
    /// of it; 0 unless [`CcdConfig::bodies_collide`](super::CcdConfig::bodies_collide). The
    /// default is 0.
    pub bodies_clamped: usize,
}
