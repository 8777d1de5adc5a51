//! [`CcdStepSystems::Impacts`](super::CcdStepSystems::Impacts): the step's [`CcdImpact`]
//! messages.

use bevy_ecs::prelude::*;

use super::compound::Compounds;
use super::workspace::CcdWorkspace;
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
    let lane_len = ws.lane_len.max(1);
    let target = |index: u32| ws.static_entities[index as usize];
    let collider = |index: u32| ws.static_colliders[index as usize];
    let mut sent = 0;
    // Lane by lane, in gathering order; each lane's `hit` list names its bodies with impacts,
    // so the others are not visited again.
    for (lane, first) in ws.lanes.iter().zip((0..ws.bodies.len()).step_by(lane_len)) {
        for &index in &lane.hit {
            let body = &ws.bodies[first + index as usize];
            let start = body.impacts as usize;
            let list = &lane.impacts[start..start + body.impact_count as usize];
            sent += list.len();
            for (k, i) in list.iter().enumerate() {
                impacts.write(CcdImpact {
                    body: body.entity,
                    body_collider: compounds.collider(body, i.part),
                    target: target(i.target),
                    target_collider: collider(i.target),
                    fraction: i.fraction,
                    point: i.point,
                    normal: i.normal,
                    substep: k as u32,
                });
            }
        }
    }
    if diagnostics.impacts != sent {
        diagnostics.impacts = sent;
    }
}
