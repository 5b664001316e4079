//! Fits that do not depend on each other, run side by side. On the CPU engine each
//! worker thread rebuilds the problem on an engine of its own ([`Problem::parts`]) and
//! takes the items one at a time; what a worker logs reaches the caller's log on the
//! caller's thread as it happens. On another engine (one GPU) the items run one after
//! the other. Every item starts from the problem as it was (the same axis search,
//! nothing cached: a cache only saves work), so the results are the same either way,
//! and they come back in the items' order.

use super::fit::Problem;
use crate::engine::cpu::CpuEngine;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;

/// What a worker tells the caller's thread.
enum Report<R> {
    Log(String),
    Done(usize, R),
}

/// `work` on every item of `items`, side by side where the engine allows (the items
/// `heavy` picks taken first, so that the longest do not start last); each item's log
/// lines go to `log`. The problem's simulation counts include the workers'.
pub fn each<'a, T, R, F>(
    problem: &mut Problem<'a, '_>,
    items: &[T],
    heavy: impl Fn(&T) -> bool,
    work: F,
    log: &dyn Fn(&str),
) -> Vec<R>
where
    T: Sync,
    R: Send,
    F: Fn(&mut Problem<'a, '_>, &T, &dyn Fn(&str)) -> R + Sync,
{
    let workers = rayon::current_num_threads().min(items.len());
    if workers < 2 || !problem.model.runs_on_cpu() {
        return items
            .iter()
            .map(|item| afresh(problem, |p| work(p, item, log)))
            .collect();
    }
    let (first, rest): (Vec<usize>, Vec<usize>) = (0..items.len()).partition(|&i| heavy(&items[i]));
    let queue = Queue {
        order: first.into_iter().chain(rest).collect(),
        next: AtomicUsize::new(0),
    };
    let (sender, receiver) = mpsc::channel();
    let mut done: Vec<Option<R>> = items.iter().map(|_| None).collect();
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                let (parts, sender) = (problem.parts(), sender.clone());
                let (queue, work) = (&queue, &work);
                scope.spawn(move || {
                    let mut engine = CpuEngine;
                    let mut worker = parts.on(&mut engine);
                    work_through(&mut worker, items, queue, work, &sender);
                    worker.model.counts()
                })
            })
            .collect();
        drop(sender);
        for report in receiver {
            match report {
                Report::Log(line) => log(&line),
                Report::Done(i, r) => done[i] = Some(r),
            }
        }
        for handle in handles {
            let counts = handle.join().expect("a fitting worker does not panic");
            problem.model.count_in(counts);
        }
    });
    done.into_iter()
        .map(|r| r.expect("every item is done"))
        .collect()
}

/// The items' indices in the order they are taken, and the next one's place in it.
struct Queue {
    order: Vec<usize>,
    next: AtomicUsize,
}

/// One worker's loop: the next item from `queue`, done on `worker` afresh, its log
/// lines and result sent to the caller's thread, until none is left.
fn work_through<'a, T, R, F>(
    worker: &mut Problem<'a, '_>,
    items: &[T],
    queue: &Queue,
    work: &F,
    sender: &mpsc::Sender<Report<R>>,
) where
    F: Fn(&mut Problem<'a, '_>, &T, &dyn Fn(&str)) -> R,
{
    let tell = |line: &str| {
        let _ = sender.send(Report::Log(line.to_string()));
    };
    while let Some(&i) = queue.order.get(queue.next.fetch_add(1, Ordering::Relaxed)) {
        let r = afresh(worker, |p| work(p, &items[i], &tell));
        let _ = sender.send(Report::Done(i, r));
    }
}

/// `work` on `problem`, then its axis search put back and what it cached forgotten.
fn afresh<'a, 'e, R>(
    problem: &mut Problem<'a, 'e>,
    work: impl FnOnce(&mut Problem<'a, 'e>) -> R,
) -> R {
    let shift = problem.shift;
    let out = work(problem);
    problem.search_from(shift);
    out
}
