//! The one work-distribution helper of the plugin: items handed out one at a time from a
//! shared counter to the calling thread and to one task per thread of the compute pool.
//!
//! Every parallel part of a step goes through [`hand_out`]: the record passes (pieces of the
//! component tables) and the solve (lanes of bodies: listed, queried, solved and written
//! back). Each item is worked on by exactly one thread and the work on an item reads only that
//! item and shared immutable data, so the results do not depend on the number of threads or
//! on which thread took which item: the same bits on one thread or many.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

use bevy_tasks::{ComputeTaskPool, TaskPool};
use smallvec::SmallVec;

use super::CcdConfig;

/// Most items a region keeps on the stack (more spill to the heap): the lanes of a step are
/// capped here, and the record passes cut about this many pieces at most.
pub(crate) const MAX_ITEMS: usize = 128;

/// The task pool to split work over, when the config asks for it and it has a thread. The
/// phases run on the thread that runs the plugin's schedules (the main thread in an app),
/// which works beside the pool's threads in every region: a pool of one thread, what Bevy's
/// default pools give a 2-core machine, already makes two workers.
pub(crate) fn pool(config: &CcdConfig) -> Option<&'static TaskPool> {
    if !config.parallel {
        return None;
    }
    let pool = ComputeTaskPool::get_or_init(TaskPool::default);
    (pool.thread_num() >= 1).then_some(&**pool)
}

/// Threads that work in a region: the pool's and the calling thread.
pub(crate) fn workers(pool: Option<&TaskPool>) -> usize {
    pool.map_or(1, |pool| pool.thread_num() + 1)
}

/// Runs the two stages of `work` on every item that `produce` hands out, then `finish` on it.
///
/// `produce` runs first on the calling thread and gives its items, at most `capacity` of
/// them, to the `push` it is passed; `finish` runs on the calling thread, the only one that
/// may touch `context` (the world's queries). Without a pool, or with one item, everything
/// runs in order on the calling thread: all items produced, the first stage of work on every
/// item, then the second stage and `finish` item by item; so each stage's data (the static
/// hierarchy for the broad phase, the targets for the solve) stays in cache across items,
/// which one thread does not get by alternating them.
///
/// On the pool, one task per pool thread starts at once and takes items by a shared counter
/// as `produce` pushes them (waiting for an item not yet pushed), so that producing the later
/// items overlaps the work on the first; the calling thread, done producing, takes items too,
/// and finishes each item worked on (by any thread) between its own items. A thread woken
/// late finds the rest done rather than waits for its share.
///
/// Why not Bevy's `par_iter`: on a pool of one thread it runs serially (it does not count the
/// calling thread), and it hands out query items one by one, which costs as much as recording
/// a body. Slices of the component tables and lanes of bodies split for free.
pub(crate) fn hand_out<T: Send, C>(
    pool: Option<&TaskPool>,
    capacity: usize,
    context: &mut C,
    produce: impl FnOnce(&mut C, &mut dyn FnMut(T)),
    work: (impl Fn(&mut T) + Sync, impl Fn(&mut T) + Sync),
    mut finish: impl FnMut(&mut C, T),
) {
    let (first, second) = &work;
    let Some(pool) = pool.filter(|_| capacity > 1) else {
        let mut items: SmallVec<[T; MAX_ITEMS]> = SmallVec::new();
        produce(context, &mut |item| items.push(item));
        items.iter_mut().for_each(first);
        for mut item in items {
            second(&mut item);
            finish(context, item);
        }
        return;
    };
    let work = |item: &mut T| {
        first(item);
        second(item);
    };
    let slots: SmallVec<[Mutex<Slot<T>>; MAX_ITEMS]> =
        (0..capacity).map(|_| Mutex::new(Slot::Pending)).collect();
    let slots = &slots[..];
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let (next, failed, work) = (&next, &failed, &work);
    pool.scope(|s| {
        for _ in 0..pool.thread_num() {
            s.spawn(async move {
                // A task that panics (a bug) leaves its item taken: the flag stops the wait
                // of the calling thread, and the scope passes the panic on.
                let _watch = PanicFlag(failed);
                while take(slots, next, failed, work) {}
            });
        }
        // A panic in `produce` (a bug) would leave items pending: the flag stops the tasks
        // waiting for them.
        let _watch = PanicFlag(failed);
        let mut pushed = 0;
        // Items beyond `capacity` (a caller's miscount) are worked on here and finished
        // with the others, never lost.
        let mut extra: SmallVec<[T; 1]> = SmallVec::new();
        produce(context, &mut |mut item| match slots.get(pushed) {
            Some(slot) => {
                *lock(slot) = Slot::Ready(item);
                pushed += 1;
            }
            None => {
                work(&mut item);
                extra.push(item);
            }
        });
        // Items `produce` did not push: nothing to work on or finish.
        for slot in slots.get(pushed..).unwrap_or_default() {
            *lock(slot) = Slot::Finished;
        }
        // `slots[..first]` are all finished.
        let mut first = 0;
        let mut flush = |context: &mut C, block: bool| {
            let handed_out = next.load(Ordering::Relaxed).min(slots.len());
            let mut k = first;
            while k < handed_out {
                let done = {
                    let mut guard = lock(&slots[k]);
                    match core::mem::replace(&mut *guard, Slot::Finished) {
                        Slot::Done(item) => Some(Some(item)),
                        Slot::Finished => Some(None),
                        // Taken, about to be.
                        pending => {
                            *guard = pending;
                            None
                        }
                    }
                };
                match done {
                    Some(item) => {
                        if let Some(item) = item {
                            finish(context, item);
                        }
                        if k == first {
                            first += 1;
                        }
                        k += 1;
                    }
                    None if block && !failed.load(Ordering::Relaxed) => std::thread::yield_now(),
                    None if block => return,
                    None => k += 1,
                }
            }
        };
        while take(slots, next, failed, work) {
            flush(context, false);
        }
        flush(context, true);
        extra.into_iter().for_each(|item| finish(context, item));
    });
}

/// One item in [`hand_out`].
enum Slot<T> {
    /// Not yet pushed: a thread that takes it waits.
    Pending,
    /// Pushed, not yet taken.
    Ready(T),
    /// Being worked on.
    Taken,
    /// Worked on, not yet finished.
    Done(T),
    /// Finished, or never pushed.
    Finished,
}

/// Takes the next item by the shared counter, works on it and marks it done; `false` when
/// every item has been handed out.
fn take<T>(
    slots: &[Mutex<Slot<T>>],
    next: &AtomicUsize,
    failed: &AtomicBool,
    work: &impl Fn(&mut T),
) -> bool {
    // The counter hands out every index once, so the slot is still ready, or still pending.
    let k = next.fetch_add(1, Ordering::Relaxed);
    let Some(slot) = slots.get(k) else {
        return false;
    };
    let mut item = loop {
        let mut guard = lock(slot);
        match core::mem::replace(&mut *guard, Slot::Taken) {
            Slot::Ready(item) => break item,
            // The listing fills a lane in a few microseconds, a tenth of the time the lane
            // takes to solve: a task waits here only for the first.
            Slot::Pending if !failed.load(Ordering::Relaxed) => {
                *guard = Slot::Pending;
                drop(guard);
                std::thread::yield_now();
            }
            other => {
                *guard = other;
                return false;
            }
        }
    };
    work(&mut item);
    *lock(slot) = Slot::Done(item);
    true
}

/// Locks a slot; a lock poisoned by a panic elsewhere still hands out its state (the panic
/// itself is passed on by the task scope).
fn lock<T>(slot: &Mutex<T>) -> MutexGuard<'_, T> {
    slot.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Raises its flag when dropped by a panic.
struct PanicFlag<'a>(&'a AtomicBool);

impl Drop for PanicFlag<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Ordering::Relaxed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pushed item goes through both stages once, in order, and is finished once, in any
    /// thread count, also when the producer pushes fewer items than its capacity, or more.
    #[test]
    fn every_item_once() {
        for threads in [0, 1, 3] {
            let pool = bevy_tasks::TaskPoolBuilder::new()
                .num_threads(threads.max(1))
                .build();
            let pool = (threads > 0).then_some(&pool);
            for (capacity, pushed) in [(0, 0), (1, 1), (5, 5), (8, 3), (4, 9), (64, 64)] {
                let mut finished = Vec::new();
                hand_out(
                    pool,
                    capacity,
                    &mut finished,
                    |_, push| (0..pushed).for_each(|i| push((i, 0u32))),
                    (
                        |(_, count): &mut _| *count += 1,
                        |(_, count): &mut _| *count *= 10,
                    ),
                    |finished, item| finished.push(item),
                );
                finished.sort_unstable();
                let expected: Vec<_> = (0..pushed).map(|i| (i, 10)).collect();
                assert_eq!(finished, expected, "{threads} threads, {capacity} slots");
            }
        }
    }
}
