//! Progress on a terminal for work that can run past a second (solves, uploads, studies, table
//! builds): drawn on stderr only when stderr is a terminal and `--quiet` was not given, cleared
//! when the work ends or fails, so an error or the result starts on a clean line. Pipes, files
//! and CI logs get none of it.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use emplan::tour::progress::{self, Event};
use indicatif::{ProgressBar, ProgressFinish, ProgressStyle};

static QUIET: AtomicBool = AtomicBool::new(false);

/// `--quiet`: no progress at all.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Whether progress is drawn.
pub fn shown() -> bool {
    !QUIET.load(Ordering::Relaxed) && std::io::stderr().is_terminal()
}

/// A bar of `len` steps with `template` (indicatif's), hidden when progress is not shown;
/// cleared when dropped.
pub fn bar(len: u64, template: &str) -> ProgressBar {
    if !shown() {
        return ProgressBar::hidden();
    }
    ProgressBar::new(len)
        .with_style(
            ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar()),
        )
        .with_finish(ProgressFinish::AndClear)
}

/// Runs the solves of `work` with a spinner naming the order being solved, the solver's phase,
/// the best tour so far and the proven bound (the gap between them).
pub fn solving<R>(what: &str, work: impl FnOnce() -> R) -> R {
    if !shown() {
        return work();
    }
    let spinner = ProgressBar::new_spinner()
        .with_style(
            ProgressStyle::with_template("{spinner} {prefix}: {msg} [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        )
        .with_prefix(what.to_string())
        .with_finish(ProgressFinish::AndClear);
    spinner.enable_steady_tick(Duration::from_millis(120));
    let shown = spinner.clone();
    let mut state = State::default();
    let out = progress::listen(
        move |event| {
            state.hear(event);
            shown.set_message(state.line());
        },
        work,
    );
    spinner.finish_and_clear();
    out
}

#[derive(Default)]
struct State {
    order: Option<&'static str>,
    phase: Option<&'static str>,
    incumbent: Option<f64>,
    bound: Option<f64>,
    kicks: Option<(u64, u64)>,
}

impl State {
    fn hear(&mut self, event: Event) {
        match event {
            Event::Order(order) => {
                *self = State {
                    order: Some(order),
                    ..State::default()
                }
            }
            Event::Phase(phase) => {
                self.phase = Some(phase);
                self.kicks = None;
            }
            Event::Incumbent(cost) => self.incumbent = Some(cost),
            Event::Bound(bound) => self.bound = Some(bound),
            Event::Kicks { done, budget } => self.kicks = Some((done, budget)),
        }
    }

    fn line(&self) -> String {
        let mut parts = Vec::new();
        if let Some(order) = self.order {
            parts.push(order.to_string());
        }
        if let Some(phase) = self.phase {
            parts.push(phase.to_string());
        }
        if let Some(best) = self.incumbent {
            parts.push(format!("best {best:.1}"));
        }
        if let Some(bound) = self.bound {
            let gap = self
                .incumbent
                .filter(|b| b.abs() > 0.0)
                .map(|b| format!(" (gap {:.2}%)", 100.0 * (b - bound) / b.abs()))
                .unwrap_or_default();
            parts.push(format!("bound {bound:.1}{gap}"));
        }
        if let Some((done, budget)) = self.kicks {
            parts.push(format!("kick {done}/{budget}"));
        }
        parts.join(", ")
    }
}
