//! Stopping a plan from outside: a [`Cancel`] token (a flag any thread may raise, and an
//! optional hard deadline) that the long loops of planning look at on the thread that plans.
//! The service plans each mission file on a blocking thread of its own; when the file is
//! deleted or changed, or the plan runs past its time limit, it raises the token and the
//! plan stops within a few milliseconds, giving its memory back.
//!
//! Like [`super::progress`], the token is thread-local: [`within`] sets it for the work it
//! runs, and the loops call [`requested`] (a thread-local read and an atomic load when a token
//! is set, the thread-local read alone when none is). Plain `std`: `plan` and `planner` never
//! import tokio. What a loop does when asked to stop is its own affair: a solver stops as if
//! its time limit had come (its best tour so far); pricing and the assignment bound return
//! [`super::PlanError::Cancelled`]; `planner::plan_mission` then answers
//! `PlannerError::Cancelled` whatever the phase.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::PlanError;

/// A plan's stop signal: raised by [`Cancel::cancel`] from any thread, or by its deadline.
/// Clones share the flag.
#[derive(Debug, Clone, Default)]
pub struct Cancel {
    flag: Arc<AtomicBool>,
    deadline: Option<Instant>,
}

impl Cancel {
    /// A token raised only by [`Cancel::cancel`].
    pub fn new() -> Cancel {
        Cancel::default()
    }

    /// The same token, also raised once `deadline` passes.
    pub fn with_deadline(self, deadline: Instant) -> Cancel {
        Cancel {
            deadline: Some(deadline),
            ..self
        }
    }

    /// Asks the plan to stop.
    pub fn cancel(&self) {
        self.flag.store(true, Ordering::Relaxed);
    }

    /// Whether [`Cancel::cancel`] was called (the deadline aside).
    pub fn cancelled(&self) -> bool {
        self.flag.load(Ordering::Relaxed)
    }

    /// Whether the deadline has passed (the flag aside).
    pub fn expired(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }

    /// Raised, by the flag or the deadline.
    pub fn requested(&self) -> bool {
        self.cancelled() || self.expired()
    }

    /// The time left before the deadline (zero once raised; `None` without a deadline).
    fn left(&self) -> Option<Duration> {
        if self.cancelled() {
            return Some(Duration::ZERO);
        }
        self.deadline
            .map(|d| d.saturating_duration_since(Instant::now()))
    }
}

thread_local! {
    static CURRENT: RefCell<Option<Cancel>> = const { RefCell::new(None) };
}

/// Puts back the token that was set before [`within`], even if its work panics.
struct Restore(Option<Cancel>);

impl Drop for Restore {
    fn drop(&mut self) {
        let before = self.0.take();
        CURRENT.with(|c| *c.borrow_mut() = before);
    }
}

/// Runs `work` with `cancel` as this thread's token.
pub fn within<R>(cancel: &Cancel, work: impl FnOnce() -> R) -> R {
    let before = CURRENT.with(|c| c.replace(Some(cancel.clone())));
    let _restore = Restore(before);
    work()
}

/// This thread's token, if any (to hand to work run on another thread with [`within`]).
pub fn current() -> Option<Cancel> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Whether this thread's token (if any) asks the plan to stop.
pub fn requested() -> bool {
    CURRENT.with(|c| c.borrow().as_ref().is_some_and(Cancel::requested))
}

/// `Err(PlanError::Cancelled)` when this thread's token asks the plan to stop.
pub fn check() -> Result<(), PlanError> {
    if requested() {
        Err(PlanError::Cancelled)
    } else {
        Ok(())
    }
}

/// `limit`, shortened to the time this thread's token leaves (a solve's time limit never runs
/// past the token's deadline).
pub fn limit(limit: Duration) -> Duration {
    CURRENT
        .with(|c| c.borrow().as_ref().and_then(Cancel::left))
        .map_or(limit, |left| limit.min(left))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_token_is_seen_only_inside_within_and_on_its_own_thread() {
        let cancel = Cancel::new();
        assert!(!requested());
        cancel.cancel();
        assert!(!requested(), "no token is set outside within");
        within(&cancel, || {
            assert!(requested());
            assert_eq!(check(), Err(PlanError::Cancelled));
            assert_eq!(limit(Duration::from_secs(5)), Duration::ZERO);
            let other = std::thread::spawn(requested).join().expect("thread");
            assert!(!other, "another thread has no token");
        });
        assert!(!requested(), "the token is gone after within");
    }

    #[test]
    fn a_deadline_raises_the_token_and_shortens_a_time_limit() {
        let past = Cancel::new().with_deadline(Instant::now());
        within(&past, || assert!(requested()));
        let later = Cancel::new().with_deadline(Instant::now() + Duration::from_secs(3600));
        within(&later, || {
            assert!(!requested());
            assert_eq!(limit(Duration::from_secs(1)), Duration::from_secs(1));
            assert!(limit(Duration::from_secs(7200)) <= Duration::from_secs(3600));
        });
        assert_eq!(limit(Duration::from_secs(7200)), Duration::from_secs(7200));
    }

    #[test]
    fn a_panic_inside_within_leaves_no_token_behind() {
        let cancel = Cancel::new();
        cancel.cancel();
        let caught = std::panic::catch_unwind(|| within(&cancel, || panic!("boom")));
        assert!(caught.is_err());
        assert!(!requested());
    }
}
