//! Entity events for observers: [`CcdImpactEvent`], [`CcdSensorEntered`] and [`CcdSensorExited`],
//! triggered on the bodies and targets that opt in with [`CcdEvents`].

use bevy_ecs::prelude::*;
use bevy_reflect::prelude::*;

use super::CcdImpact;
use super::sensors::CcdSensorCrossing;

/// Opts an entity (a CCD body, a static target or a sensor) in to the entity events of its
/// impacts and sensor crossings: [`CcdImpactEvent`], [`CcdSensorEntered`], [`CcdSensorExited`], for
/// observers (`On<CcdImpactEvent>`). An app without the marker pays nothing for them; the messages
/// ([`CcdImpact`], [`CcdSensorCrossing`]) are sent either way.
///
/// The events are triggered after the step's poses are written
/// ([`CcdStepSystems::Impacts`](super::CcdStepSystems::Impacts), applied as commands at the end
/// of [`CcdSchedule`](super::CcdSchedule)): every [`CcdImpactEvent`] in the order of the impact messages,
/// then the sensor events in the order of the crossing messages; for each one, the body's event
/// before the target's.
///
/// ```
/// use bevy_app::prelude::*;
/// use bevy_ccd::prelude::*;
/// use bevy_ecs::prelude::*;
/// use bevy_transform::prelude::Transform;
///
/// let mut app = App::new();
/// app.add_plugins((bevy_time::TimePlugin, CcdPlugin::default()));
/// app.world_mut()
///     .spawn((
///         Collider::circle(0.05).unwrap(),
///         CcdEnabled::default(),
///         CcdEvents,
///         Transform::default(),
///     ))
///     .observe(|hit: On<CcdImpactEvent>| println!("hit {:?} at {}", hit.impact.target, hit.impact.fraction));
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default, Debug, Clone)]
pub struct CcdEvents;

/// An impact, as an entity event on the body and on the target that carry [`CcdEvents`].
#[derive(EntityEvent, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct CcdImpactEvent {
    /// The entity the event is on: the body, or the target.
    #[event_target]
    pub entity: Entity,
    /// The impact, as its [`CcdImpact`] message has it.
    pub impact: CcdImpact,
    /// `true` on the body, `false` on the target.
    pub on_body: bool,
}

/// A body entering a sensor, as an entity event on the body and on the sensor that carry
/// [`CcdEvents`].
#[derive(EntityEvent, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct CcdSensorEntered {
    /// The entity the event is on: the body, or the sensor.
    #[event_target]
    pub entity: Entity,
    /// The crossing, as its [`CcdSensorCrossing`] message has it.
    pub crossing: CcdSensorCrossing,
    /// `true` on the body, `false` on the sensor.
    pub on_body: bool,
}

/// A body leaving a sensor, as an entity event on the body and on the sensor that carry
/// [`CcdEvents`].
#[derive(EntityEvent, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct CcdSensorExited {
    /// The entity the event is on: the body, or the sensor.
    #[event_target]
    pub entity: Entity,
    /// The crossing, as its [`CcdSensorCrossing`] message has it.
    pub crossing: CcdSensorCrossing,
    /// `true` on the body, `false` on the sensor.
    pub on_body: bool,
}

/// [`CcdStepSystems::Impacts`](super::CcdStepSystems::Impacts), after the messages: triggers
/// the entity events of this step's messages on the entities with [`CcdEvents`]. Reads the
/// messages it follows, so the order is theirs; with no marker in the world it only skips them.
/// Whether there is one is asked of the query (the tables that hold the marker), not counted
/// by hooks: an entity given the marker before the plugin was added counts too.
pub(crate) fn trigger_events(
    mut impacts: MessageReader<CcdImpact>,
    mut crossings: MessageReader<CcdSensorCrossing>,
    marked: Query<(), With<CcdEvents>>,
    mut commands: Commands,
) {
    if marked.is_empty() {
        impacts.clear();
        crossings.clear();
        return;
    }
    for &impact in impacts.read() {
        for (entity, on_body) in [(impact.body, true), (impact.target, false)] {
            if marked.contains(entity) {
                commands.trigger(CcdImpactEvent {
                    entity,
                    impact,
                    on_body,
                });
            }
        }
    }
    for &crossing in crossings.read() {
        for (entity, on_body) in [(crossing.body, true), (crossing.sensor, false)] {
            if !marked.contains(entity) {
                continue;
            }
            if crossing.entered {
                commands.trigger(CcdSensorEntered {
                    entity,
                    crossing,
                    on_body,
                });
            } else {
                commands.trigger(CcdSensorExited {
                    entity,
                    crossing,
                    on_body,
                });
            }
        }
    }
}
