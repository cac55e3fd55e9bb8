//! Progress of a long solve, for whoever listens on the solving thread: the phase it is in, the
//! best tour so far and the best lower bound. Solvers call [`report`], which costs a
//! thread-local read when nobody listens (the study's parallel solves never do); the command
//! line draws it as a progress line, the library never prints.

use std::cell::RefCell;
use std::rc::Rc;

/// What a solve has reached.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// Which order is being solved (`energy`, `distance`, ...).
    Order(&'static str),
    /// A solver phase began (`heuristic`, `branch-and-cut`, `lower bound`, `Held-Karp`).
    Phase(&'static str),
    /// A better tour was found, of this cost.
    Incumbent(f64),
    /// A better lower bound was proven.
    Bound(f64),
    /// The heuristic's kicks so far, of its budget.
    Kicks { done: u64, budget: u64 },
}

type Sink = Box<dyn FnMut(Event)>;

thread_local! {
    static SINK: RefCell<Option<Sink>> = const { RefCell::new(None) };
}

/// Runs `work` with `sink` hearing every [`Event`] reported on this thread meanwhile.
pub fn listen<R>(sink: impl FnMut(Event) + 'static, work: impl FnOnce() -> R) -> R {
    let before = SINK.with(|s| s.replace(Some(Box::new(sink))));
    let out = work();
    SINK.with(|s| *s.borrow_mut() = before);
    out
}

/// Tells the listener, if any, that `event` happened.
pub fn report(event: Event) {
    SINK.with(|s| {
        if let Ok(mut sink) = s.try_borrow_mut() {
            if let Some(sink) = sink.as_mut() {
                sink(event);
            }
        }
    });
}

/// Runs `work` with every event it reports passed through `map` before the listener hears it
/// (`None`: not at all), as a solver run on a transformed problem reports in the original's
/// terms. Without a listener, `work` runs as is.
pub fn translated<R>(
    map: impl Fn(Event) -> Option<Event> + 'static,
    work: impl FnOnce() -> R,
) -> R {
    let Some(outer) = SINK.with(|s| s.borrow_mut().take()) else {
        return work();
    };
    let outer = Rc::new(RefCell::new(outer));
    let inner = Rc::clone(&outer);
    let wrapper: Sink = Box::new(move |e| {
        if let Some(e) = map(e) {
            (inner.borrow_mut())(e);
        }
    });
    SINK.with(|s| *s.borrow_mut() = Some(wrapper));
    // Puts the listener back even if `work` panics.
    struct Restore(Rc<RefCell<Sink>>);
    impl Drop for Restore {
        fn drop(&mut self) {
            // Dropping the wrapper releases its handle on the listener.
            drop(SINK.with(|s| s.borrow_mut().take()));
            let placeholder: Sink = Box::new(|_| {});
            let outer = std::mem::replace(&mut *self.0.borrow_mut(), placeholder);
            SINK.with(|s| *s.borrow_mut() = Some(outer));
        }
    }
    let _restore = Restore(outer);
    work()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tour::{solver, CostMatrix};
    use std::rc::Rc;

    #[test]
    fn a_listener_hears_the_phases_and_an_improving_incumbent_and_others_hear_nothing() {
        let n = 40;
        let m = CostMatrix::from_fn(n, |i, j| {
            ((i * 7 + j * 13) % 17) as f64 + (i as f64 - j as f64).abs()
        });
        let heard = Rc::new(RefCell::new(Vec::new()));
        let h = heard.clone();
        let solved = listen(
            move |e| h.borrow_mut().push(e),
            || {
                solver::solve(
                    &m,
                    &solver::Options {
                        solver: solver::Solver::BranchCut,
                        ..Default::default()
                    },
                )
            },
        )
        .unwrap();
        let heard = heard.borrow();
        assert!(heard.contains(&Event::Phase("heuristic")), "{heard:?}");
        assert!(heard.contains(&Event::Phase("branch-and-cut")), "{heard:?}");
        let incumbents: Vec<f64> = heard
            .iter()
            .filter_map(|e| match e {
                Event::Incumbent(c) => Some(*c),
                _ => None,
            })
            .collect();
        assert!(!incumbents.is_empty());
        assert!(
            incumbents.windows(2).all(|w| w[1] <= w[0]),
            "{incumbents:?}"
        );
        assert!(*incumbents.last().unwrap() >= solved.tour.cost - 1e-9);
        // After the listener is gone, reports go nowhere.
        report(Event::Phase("nobody"));
    }

    #[test]
    fn a_translated_run_is_heard_through_its_map_and_the_listener_is_back_after() {
        let heard = Rc::new(RefCell::new(Vec::new()));
        let h = heard.clone();
        listen(
            move |e| h.borrow_mut().push(e),
            || {
                report(Event::Incumbent(10.0));
                translated(
                    |e| match e {
                        Event::Incumbent(c) => Some(Event::Incumbent(c - 100.0)),
                        Event::Phase(_) => None,
                        other => Some(other),
                    },
                    || {
                        report(Event::Incumbent(105.0));
                        report(Event::Phase("hidden"));
                        report(Event::Bound(3.0));
                    },
                );
                report(Event::Incumbent(4.0));
            },
        );
        assert_eq!(
            *heard.borrow(),
            [
                Event::Incumbent(10.0),
                Event::Incumbent(5.0),
                Event::Bound(3.0),
                Event::Incumbent(4.0)
            ]
        );
        // Without a listener the work just runs.
        assert_eq!(translated(Some, || 7), 7);
    }
}
