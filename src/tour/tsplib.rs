//! Reader for TSPLIB asymmetric TSP instances (Reinelt 1991; `TYPE: ATSP`,
//! `EDGE_WEIGHT_TYPE: EXPLICIT`, `EDGE_WEIGHT_FORMAT: FULL_MATRIX`). Rows may wrap over several
//! lines, so the N*N weights after `EDGE_WEIGHT_SECTION` are read as one stream; the diagonal is
//! ignored. Node 1 of the file becomes node 0 (the depot) of the cost matrix. Also the writer
//! (`emplan plan --export-atsp`) and the JSON view of a solved instance (`emplan tsp --json`).

use serde::Serialize;

use super::solver::{Solved, Solver};
use super::CostMatrix;

/// A TSPLIB instance.
#[derive(Debug, Clone, PartialEq)]
pub struct Instance {
    pub name: String,
    pub dimension: usize,
    pub matrix: CostMatrix,
}

/// Errors reading a TSPLIB file; each names the line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TsplibError {
    #[error("line {line}: {problem}")]
    Invalid { line: usize, problem: String },
    #[error("the file ends before {missing} of the {expected} edge weights")]
    Truncated { missing: usize, expected: usize },
}

/// `emplan tsp --json` (docs/json.md): the tour in TSPLIB's 1-based node ids, from node 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolutionJson {
    pub instance: String,
    pub dimension: usize,
    pub cost: f64,
    pub optimal: bool,
    pub lower_bound: f64,
    pub tour: Vec<usize>,
    pub seconds: f64,
    pub solver: Solver,
    pub gap_pct: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heuristic_cost: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nodes: Option<u64>,
}

/// The JSON view of `instance` solved.
pub fn solution_json(instance: &Instance, solved: &Solved) -> SolutionJson {
    let tour = &solved.tour;
    SolutionJson {
        instance: instance.name.clone(),
        dimension: instance.dimension,
        cost: tour.cost,
        optimal: tour.optimal,
        lower_bound: tour.lower_bound,
        tour: std::iter::once(1)
            .chain(tour.order.iter().map(|&k| k + 1))
            .collect(),
        seconds: solved.seconds,
        solver: solved.solver,
        gap_pct: solved.gap_pct,
        heuristic_cost: solved.heuristic_cost,
        nodes: solved.nodes,
    }
}

/// Largest dimension accepted (a 10 000-node matrix is 800 MB of `f64`).
pub const MAX_DIMENSION: usize = 10_000;

/// Parses a TSPLIB ATSP instance.
pub fn parse(text: &str) -> Result<Instance, TsplibError> {
    let bad = |line: usize, problem: String| TsplibError::Invalid { line, problem };
    let mut name = String::from("unnamed");
    let mut dimension: Option<usize> = None;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let mut weights_line = None;
    for (n, line) in lines.by_ref() {
        if line.is_empty() {
            continue;
        }
        if line.starts_with("EDGE_WEIGHT_SECTION") {
            weights_line = Some(n);
            break;
        }
        let (key, value) = line
            .split_once(':')
            .map(|(k, v)| (k.trim(), v.trim()))
            .unwrap_or((line, ""));
        match key {
            "NAME" => name = value.to_string(),
            "TYPE" if value != "ATSP" && value != "TSP" => {
                return Err(bad(
                    n,
                    format!("TYPE {value:?} is not supported (allowed: ATSP, TSP)"),
                ))
            }
            "DIMENSION" => {
                let d: usize = value.parse().map_err(|_| {
                    bad(n, format!("DIMENSION {value:?} is not a positive integer"))
                })?;
                if d == 0 || d > MAX_DIMENSION {
                    return Err(bad(
                        n,
                        format!("DIMENSION {d} is out of range (1 to {MAX_DIMENSION})"),
                    ));
                }
                dimension = Some(d);
            }
            "EDGE_WEIGHT_TYPE" if value != "EXPLICIT" => {
                return Err(bad(
                    n,
                    format!("EDGE_WEIGHT_TYPE {value:?} is not supported (allowed: EXPLICIT)"),
                ))
            }
            "EDGE_WEIGHT_FORMAT" if value != "FULL_MATRIX" => {
                return Err(bad(
                    n,
                    format!("EDGE_WEIGHT_FORMAT {value:?} is not supported (allowed: FULL_MATRIX)"),
                ))
            }
            _ => {}
        }
    }
    let header_end =
        weights_line.ok_or_else(|| bad(text.lines().count(), "no EDGE_WEIGHT_SECTION".into()))?;
    let dimension = dimension
        .ok_or_else(|| bad(header_end, "no DIMENSION before EDGE_WEIGHT_SECTION".into()))?;
    let expected = dimension * dimension;
    let mut weights = Vec::with_capacity(expected);
    'read: for (n, line) in lines {
        if line == "EOF" {
            break;
        }
        for token in line.split_whitespace() {
            if weights.len() == expected {
                break 'read;
            }
            let w: f64 = token
                .parse()
                .map_err(|_| bad(n, format!("edge weight {token:?} is not a number")))?;
            if !w.is_finite() {
                return Err(bad(n, format!("edge weight {token:?} is not finite")));
            }
            weights.push(w);
        }
    }
    if weights.len() < expected {
        return Err(TsplibError::Truncated {
            missing: expected - weights.len(),
            expected,
        });
    }
    Ok(Instance {
        name,
        dimension,
        matrix: CostMatrix::from_fn(dimension, |i, j| weights[i * dimension + j]),
    })
}

/// Writes `matrix` as a TSPLIB ATSP instance with every cost multiplied by `scale` and rounded
/// to an integer (TSPLIB solvers such as LKH-3 take integers only); the diagonal is written as 0.
/// Refuses a cost that is negative or non-finite, or whose scaled value does not fit in
/// 2^53 (so that the integers stay exact).
pub fn to_text(name: &str, matrix: &CostMatrix, scale: f64) -> Result<String, TsplibError> {
    use std::fmt::Write;
    let n = matrix.len();
    let mut out = format!(
        "NAME: {name}\nTYPE: ATSP\nCOMMENT: written by emplan; costs x {scale}\nDIMENSION: {n}\n\
         EDGE_WEIGHT_TYPE: EXPLICIT\nEDGE_WEIGHT_FORMAT: FULL_MATRIX\nEDGE_WEIGHT_SECTION\n"
    );
    for i in 0..n {
        let mut row = Vec::with_capacity(n);
        for j in 0..n {
            let c = if i == j {
                0.0
            } else {
                (matrix.cost(i, j) * scale).round()
            };
            if !(c.is_finite() && (0.0..=9.0e15).contains(&c)) {
                return Err(TsplibError::Invalid {
                    line: 8 + i,
                    problem: format!(
                        "cost {} -> {} ({}) cannot be written as a non-negative integer",
                        i + 1,
                        j + 1,
                        matrix.cost(i, j)
                    ),
                });
            }
            row.push(format!("{c:.0}"));
        }
        let _ = writeln!(out, "{}", row.join(" "));
    }
    out.push_str("EOF\n");
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "NAME: tiny\nTYPE: ATSP\nDIMENSION: 3\nEDGE_WEIGHT_TYPE: EXPLICIT\n\
        EDGE_WEIGHT_FORMAT: FULL_MATRIX\nEDGE_WEIGHT_SECTION\n9999 1 5\n7 9999\n2 3 4 9999\nEOF\n";

    #[test]
    fn rows_that_wrap_over_lines_are_read_as_one_stream_and_the_diagonal_is_ignored() {
        let inst = parse(SMALL).unwrap();
        assert_eq!(inst.name, "tiny");
        assert_eq!(inst.dimension, 3);
        assert_eq!(inst.matrix.cost(0, 1), 1.0);
        assert_eq!(inst.matrix.cost(1, 0), 7.0);
        assert_eq!(inst.matrix.cost(1, 2), 2.0);
        assert_eq!(inst.matrix.cost(2, 0), 3.0);
        assert_eq!(inst.matrix.cost(0, 0), 0.0);
    }

    #[test]
    fn a_bad_weight_is_reported_with_its_line() {
        let text = SMALL.replace("7 9999", "7 x");
        assert_eq!(
            parse(&text),
            Err(TsplibError::Invalid {
                line: 8,
                problem: "edge weight \"x\" is not a number".into()
            })
        );
    }

    #[test]
    fn a_truncated_matrix_says_how_many_weights_are_missing() {
        let text = SMALL.replace("2 3 4 9999\n", "");
        assert_eq!(
            parse(&text),
            Err(TsplibError::Truncated {
                missing: 4,
                expected: 9
            })
        );
    }

    #[test]
    fn a_written_instance_reads_back_with_its_scaled_costs() {
        let m = CostMatrix::from_fn(4, |i, j| (i * 10 + j) as f64 + 0.1234);
        let text = to_text("four", &m, 1000.0).unwrap();
        let back = parse(&text).unwrap();
        assert_eq!(back.dimension, 4);
        assert_eq!(back.matrix.cost(2, 3), 23123.0);
        assert_eq!(back.matrix.cost(3, 0), 30123.0);
        let bad = CostMatrix::from_fn(2, |_, _| -1.0);
        assert!(to_text("bad", &bad, 1.0).is_err());
    }

    #[test]
    fn unsupported_formats_are_named() {
        let text = SMALL.replace("FULL_MATRIX", "UPPER_ROW");
        assert!(matches!(
            parse(&text),
            Err(TsplibError::Invalid { line: 5, .. })
        ));
        assert!(matches!(
            parse("NAME: x\n"),
            Err(TsplibError::Invalid { .. })
        ));
    }
}
