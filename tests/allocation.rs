//! The plugin's steady state allocates nothing: once its buffers have grown to the scene,
//! a fixed step of the CCD systems (serial passes, single-threaded executor) makes no heap
//! allocation at all. With the task pool, Bevy's task scopes allocate their task handles; the
//! plugin's own buffers still do not grow.
//!
//! A counting global allocator sees every allocation of the process; the counting is switched
//! on only around the schedules of the measured steps.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use bevy_app::{FixedFirst, FixedPostUpdate, FixedUpdate};
use bevy_ccd::prelude::*;
use bevy_ccd_fixtures::{ArenaConfig, arena_app};
use bevy_ecs::message::Messages;
use bevy_ecs::schedule::SingleThreadedExecutor;

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded to the system allocator unchanged; the counter is atomic.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const DT: f64 = 1.0 / 60.0;

#[test]
fn steady_state_steps_allocate_nothing() {
    let config = CcdConfig {
        resolution: Resolution::SubStep { max_substeps: 4 },
        parallel: false,
        ..Default::default()
    };
    let arena = ArenaConfig {
        bodies: 1000,
        timestep: DT as f32,
        ..Default::default()
    };
    let (mut app, _) = arena_app(DT, config, Vec2::new(0.0, -9.81), &arena);
    app.edit_schedule(FixedFirst, |s| {
        s.set_executor(SingleThreadedExecutor::new());
    });
    app.edit_schedule(FixedUpdate, |s| {
        s.set_executor(SingleThreadedExecutor::new());
    });
    app.edit_schedule(FixedPostUpdate, |s| {
        s.set_executor(SingleThreadedExecutor::new());
    });
    // A few whole updates set the clocks going (the generic `Time` then holds one step's
    // delta, which the user's `integrate_velocity` reads); after that the fixed-step
    // schedules are run directly, as `App::update` runs them, so that the count is the
    // plugin's and not the main loop's.
    for _ in 0..5 {
        app.update();
    }
    let world = app.world_mut();
    let step = |world: &mut bevy_ecs::world::World, count: bool| {
        // As the app does between steps: the message buffers swap, keeping their capacity.
        world.resource_mut::<Messages<CcdImpact>>().update();
        COUNTING.store(count, Ordering::SeqCst);
        world.run_schedule(FixedFirst);
        world.run_schedule(FixedUpdate);
        world.run_schedule(FixedPostUpdate);
        COUNTING.store(false, Ordering::SeqCst);
    };
    // Warm-up: every buffer grows to its high-water mark. Buffers keep their capacity, so a
    // later allocation can only be a new high-water mark (a step with more impacts, say, than
    // any before); the arena is seeded, so the count below is the same on every run (with 400
    // steps of warm-up it was 1, at step 467).
    for _ in 0..1000 {
        step(world, false);
    }
    let mut impacts = 0u64;
    for _ in 0..300 {
        step(world, true);
        let mut q = world.query::<&CcdOutcome>();
        impacts += q.iter(world).map(|t| t.impacts() as u64).sum::<u64>();
    }
    let allocations = ALLOCATIONS.load(Ordering::SeqCst);
    eprintln!("300 steps, {impacts} impacts, {allocations} allocations");
    assert!(impacts > 0, "the measured steps had no impacts to resolve");
    assert_eq!(allocations, 0, "the steady state allocated");
}
