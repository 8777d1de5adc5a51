//! [`CcdStepSystems::Impacts`](super::CcdStepSystems::Impacts): the step's [`CcdImpact`]
//! messages.

use bevy_ecs::prelude::*;

use super::compound::Compounds;
use super::workspace::CcdWorkspace;
use super::write::WriteLookups;
use super::{CcdDiagnostics, CcdImpact};

/// [`CcdStepSystems::Impacts`](super::CcdStepSystems::Impacts): the impact messages, lane by
/// lane in listing order (the components were written by the solve).
pub(crate) fn send_impacts(
    workspace: Res<CcdWorkspace>,
    compounds: Res<Compounds>,
    mut diagnostics: ResMut<CcdDiagnostics>,
    mut impacts: MessageWriter<CcdImpact>,
) {
    let ws: &CcdWorkspace = &workspace;
    let lookups = WriteLookups {
        entities: &ws.statics.entities,
        colliders: &ws.statics.colliders,
        child_frames: &ws.bodies.child_frames,
        bodies: &ws.bodies.entries,
    };
    let mut sent = 0;
    // Lane by lane, in gathering order; each lane's `hit` list names its bodies with impacts,
    // so the others are not visited again.
    for (lane, bodies) in ws.bodies.by_lane() {
        for &index in &lane.hit {
            let body = &bodies[index as usize];
            let start = body.impacts as usize;
            let list = &lane.impacts[start..start + body.impact_count as usize];
            sent += list.len();
            for (k, record) in list.iter().enumerate() {
                impacts.write(lookups.impact(body, record, k as u32, &compounds));
            }
        }
    }
    if diagnostics.impacts != sent {
        diagnostics.impacts = sent;
    }
}
