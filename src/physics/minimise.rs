//! General minimisers: golden-section search of a unimodal function of one variable, and the
//! Nelder-Mead simplex in several. A leaf: the PTF's duration search, the paper fit and the
//! log fits all use it, and it imports nothing of the model.

/// What a golden-section search ends with: its last bracket and the better of the two points
/// inside it, with its value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GoldenSection {
    pub low: f64,
    pub high: f64,
    pub best: f64,
    pub best_value: f64,
}

/// Golden-section search for the minimum of `f`, unimodal on `bracket`: at most `iterations`
/// steps, stopping early once the bracket is narrower than `tolerance` (0: never).
pub(crate) fn golden_section(
    f: &impl Fn(f64) -> f64,
    bracket: (f64, f64),
    tolerance: f64,
    iterations: usize,
) -> GoldenSection {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = bracket;
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iterations {
        if fc <= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - ratio * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + ratio * (b - a);
            fd = f(d);
        }
        if b - a < tolerance {
            break;
        }
    }
    let (best, best_value) = if fc <= fd { (c, fc) } else { (d, fd) };
    GoldenSection {
        low: a,
        high: b,
        best,
        best_value,
    }
}

/// Nelder-Mead simplex minimisation (Nelder & Mead 1965; standard coefficients 1, 2, 0.5, 0.5).
pub(crate) fn nelder_mead(
    start: &[f64],
    step: &[f64],
    iterations: usize,
    f: &impl Fn(&[f64]) -> f64,
) -> Vec<f64> {
    simplex_search(start, step, iterations, 0.0, f).0
}

/// Nelder-Mead restarted from its own result with a fresh simplex of `step` until a restart
/// no longer lowers the value by more than `tolerance` (relative), at most `restarts` times;
/// each run stops early once its simplex's values agree within `tolerance` (relative). A
/// simplex can collapse onto a face of the search space (a parameter pressed against a bound,
/// parameters that trade against each other) and stall short of the minimum; a fresh simplex
/// at the point reached spans every direction again (the standard remedy: Press et al.,
/// Numerical Recipes 3rd ed., section 10.5). Returns the point and its value.
pub(crate) fn nelder_mead_restarted(
    start: &[f64],
    step: &[f64],
    iterations: usize,
    restarts: usize,
    tolerance: f64,
    f: &impl Fn(&[f64]) -> f64,
) -> (Vec<f64>, f64) {
    let (mut best, mut value) = simplex_search(start, step, iterations, tolerance, f);
    for _ in 0..restarts {
        let (x, fx) = simplex_search(&best, step, iterations, tolerance, f);
        let better = fx < value - tolerance * value.abs();
        if fx < value {
            (best, value) = (x, fx);
        }
        if !better {
            break;
        }
    }
    (best, value)
}

/// The simplex search of [`nelder_mead`]: at most `iterations` steps, stopping early once the
/// simplex's values agree within `tolerance` relative to the best (0: never). Returns the best
/// vertex and its value.
fn simplex_search(
    start: &[f64],
    step: &[f64],
    iterations: usize,
    tolerance: f64,
    f: &impl Fn(&[f64]) -> f64,
) -> (Vec<f64>, f64) {
    let n = start.len();
    let mut simplex: Vec<(Vec<f64>, f64)> = (0..=n)
        .map(|k| {
            let mut x = start.to_vec();
            if k > 0 {
                x[k - 1] += step[k - 1];
            }
            let fx = f(&x);
            (x, fx)
        })
        .collect();
    for _ in 0..iterations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        if tolerance > 0.0 && simplex[n].1 - simplex[0].1 <= tolerance * simplex[0].1.abs() {
            break;
        }
        let centroid: Vec<f64> = (0..n)
            .map(|i| simplex[..n].iter().map(|(x, _)| x[i]).sum::<f64>() / n as f64)
            .collect();
        let toward = |t: f64| -> Vec<f64> {
            centroid
                .iter()
                .zip(&simplex[n].0)
                .map(|(c, w)| c + t * (w - c))
                .collect()
        };
        let reflected = toward(-1.0);
        let fr = f(&reflected);
        if fr < simplex[0].1 {
            let expanded = toward(-2.0);
            let fe = f(&expanded);
            simplex[n] = if fe < fr {
                (expanded, fe)
            } else {
                (reflected, fr)
            };
        } else if fr < simplex[n - 1].1 {
            simplex[n] = (reflected, fr);
        } else {
            let contracted = toward(0.5);
            let fc = f(&contracted);
            if fc < simplex[n].1 {
                simplex[n] = (contracted, fc);
            } else {
                let best = simplex[0].0.clone();
                for entry in simplex.iter_mut().skip(1) {
                    let x: Vec<f64> = best
                        .iter()
                        .zip(&entry.0)
                        .map(|(b, x)| b + 0.5 * (x - b))
                        .collect();
                    let fx = f(&x);
                    *entry = (x, fx);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex.swap_remove(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_section_finds_the_minimum_of_a_parabola_inside_its_bracket() {
        let search = golden_section(&|x: f64| (x - 1.3).powi(2) + 2.0, (0.0, 4.0), 1e-9, 200);
        assert!((search.best - 1.3).abs() < 1e-6, "{search:?}");
        assert!((search.best_value - 2.0).abs() < 1e-9);
        assert!(search.low <= search.best && search.best <= search.high);
    }

    #[test]
    fn nelder_mead_finds_the_minimum_of_a_bowl_in_two_dimensions() {
        let bowl = |x: &[f64]| (x[0] - 0.5).powi(2) + 3.0 * (x[1] + 2.0).powi(2);
        let best = nelder_mead(&[3.0, 3.0], &[1.0, 1.0], 200, &bowl);
        assert!(
            (best[0] - 0.5).abs() < 1e-4 && (best[1] + 2.0).abs() < 1e-4,
            "{best:?}"
        );
    }
}
