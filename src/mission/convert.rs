//! What a conversion between mission formats keeps: a mission is written in the target format,
//! read back, and compared setting by setting with the original, so that `emplan convert` can
//! refuse (or, when asked, list) every setting the target format drops or changes. Positions
//! are compared in the origin's local frame to a millimetre, hover times to a millisecond:
//! what is below a format's printed precision is not a loss.

use std::path::Path;

use super::fence::{LatLon, RallyPoint, Shape};
use super::{load_str, to_string, Format, Geodetic, Mission, MissionError};

/// One setting the conversion would not carry over as it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Loss {
    /// The setting, as the mission file names it (`min_height_above_home_m`, `waypoint C
    /// hover_s`).
    pub setting: String,
    /// Its value in the original, as text.
    pub from: String,
    /// What the converted file holds instead.
    pub to: String,
}

impl std::fmt::Display for Loss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {} -> {}", self.setting, self.from, self.to)
    }
}

/// Records `setting` when `b` is more than `tolerance` from `a`.
fn number(out: &mut Vec<Loss>, setting: String, a: f64, b: f64, tolerance: f64) {
    if (a - b).abs() > tolerance || a.is_nan() != b.is_nan() {
        out.push(Loss {
            setting,
            from: format!("{a}"),
            to: format!("{b}"),
        });
    }
}

const POSITION_TOLERANCE_M: f64 = 1e-3;
const TIME_TOLERANCE_S: f64 = 1e-3;

/// The text of `mission` for the file `output` (its extension chooses the format) and every
/// setting that file would not give back.
pub fn convert(mission: &Mission, output: &Path) -> Result<(String, Vec<Loss>), MissionError> {
    let format = Format::from_path(output)?;
    if format == Format::Wpl {
        if let Some(e) = mission.cannot_be_wpl(&output.display().to_string()) {
            return Err(e);
        }
    }
    // A .waypoints file cannot hold blocks: its waypoints are written and the blocks are
    // listed as lost (`emplan convert` refuses that without --lossy).
    let text = match format {
        Format::Wpl => super::wpl::write(mission),
        _ => to_string(mission, format)?,
    };
    let back = load_str(&text, format, Some(output))?;
    Ok((text, losses(mission, &back)))
}

/// The settings of `original` that `converted` does not hold as they are.
pub fn losses(original: &Mission, converted: &Mission) -> Vec<Loss> {
    let mut out = Vec::new();
    let (o, c) = (&original.origin, &converted.origin);
    // Home moved: its offset in the original's frame.
    let home_shift = original.origin.to_enu(c.home);
    let shift_m = (home_shift.x_east_m.powi(2) + home_shift.y_north_m.powi(2)).sqrt();
    number(
        &mut out,
        "origin home (horizontal shift, m)".into(),
        0.0,
        shift_m,
        POSITION_TOLERANCE_M,
    );
    number(
        &mut out,
        "origin home_alt_amsl_m".into(),
        o.home.alt_m,
        c.home.alt_m,
        POSITION_TOLERANCE_M,
    );
    number(
        &mut out,
        "origin height_above_home_m".into(),
        o.height_above_home_m,
        c.height_above_home_m,
        POSITION_TOLERANCE_M,
    );
    number(
        &mut out,
        "default_hover_s".into(),
        original.default_hover_s,
        converted.default_hover_s,
        TIME_TOLERANCE_S,
    );
    number(
        &mut out,
        "min_height_above_home_m".into(),
        original.min_height_above_home_m,
        converted.min_height_above_home_m,
        POSITION_TOLERANCE_M,
    );
    for (k, w) in original.waypoints.iter().enumerate() {
        let Some(v) = converted.waypoints.get(k) else {
            break;
        };
        let (a, b) = (w.position, v.position);
        let moved_m = ((a.x_east_m - b.x_east_m).powi(2)
            + (a.y_north_m - b.y_north_m).powi(2)
            + (a.z_up_m - b.z_up_m).powi(2))
        .sqrt();
        number(
            &mut out,
            format!("waypoint {} position (moved, m)", w.name),
            0.0,
            moved_m,
            POSITION_TOLERANCE_M,
        );
        number(
            &mut out,
            format!("waypoint {} hover_s", w.name),
            w.hover_s,
            v.hover_s,
            TIME_TOLERANCE_S,
        );
        if w.name != v.name {
            out.push(Loss {
                setting: format!("waypoint {} name", k + 1),
                from: w.name.clone(),
                to: v.name.clone(),
            });
        }
    }
    let commands =
        |setting: String, a: &[super::actions::Command], b: &[super::actions::Command]| {
            let same = a.len() == b.len()
                && a.iter().zip(b).all(|(x, y)| {
                    x.command == y.command
                        && x.frame == y.frame
                        && x.params.iter().zip(&y.params).all(|(p, q)| {
                            (p.is_nan() && q.is_nan()) || (p - q).abs() <= 1e-7 * p.abs().max(1.0)
                        })
                });
            let show = |cs: &[super::actions::Command]| {
                cs.iter()
                    .map(|c| c.command.to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            (!same).then(|| Loss {
                setting,
                from: format!("[{}]", show(a)),
                to: format!("[{}]", show(b)),
            })
        };
    out.extend(commands(
        "start actions".into(),
        &original.start_actions,
        &converted.start_actions,
    ));
    for (w, v) in original.waypoints.iter().zip(&converted.waypoints) {
        out.extend(commands(
            format!("waypoint {} actions", w.name),
            &w.actions,
            &v.actions,
        ));
        if w.kind != v.kind {
            out.push(Loss {
                setting: format!("waypoint {} kind", w.name),
                from: format!("{:?}", w.kind),
                to: format!("{:?}", v.kind),
            });
        }
    }
    fence_losses(&mut out, original, converted);
    block_losses(&mut out, original, converted);
    if original.name != converted.name {
        out.push(Loss {
            setting: "name".into(),
            from: original.name.clone(),
            to: converted.name.clone(),
        });
    }
    if original.waypoints.len() != converted.waypoints.len() {
        out.push(Loss {
            setting: "waypoints (count)".into(),
            from: original.waypoints.len().to_string(),
            to: converted.waypoints.len().to_string(),
        });
    }
    out
}

/// What a block is, in one phrase: "survey of waypoints WP1-WP24, reversible".
fn block_summary(m: &Mission, b: &super::blocks::Block) -> String {
    let name = |k: usize| m.waypoints.get(k).map_or("?", |w| w.name.as_str());
    format!(
        "{} of waypoints {}-{}, {}",
        b.kind.word(),
        name(b.first),
        name(b.first + b.len - 1),
        if b.reversible {
            "reversible"
        } else {
            "one way"
        }
    )
}

/// The complex item a block was read from, without its generated items (those are the
/// block's waypoints, compared as waypoints).
fn settings_of(source: &serde_json::Value) -> serde_json::Value {
    let mut s = source.clone();
    if let Some(t) = s
        .get_mut("TransectStyleComplexItem")
        .and_then(serde_json::Value::as_object_mut)
    {
        t.remove("Items");
    }
    s
}

/// The blocks, one by one in file order: each named, its kind, waypoints, direction and
/// complex item's settings as they were.
fn block_losses(out: &mut Vec<Loss>, original: &Mission, converted: &Mission) {
    for (k, a) in original.blocks.iter().enumerate() {
        let setting = format!("block {:?}", a.name);
        let Some(b) = converted.blocks.get(k) else {
            out.push(Loss {
                setting,
                from: block_summary(original, a),
                to: "none (its waypoints kept as points)".into(),
            });
            continue;
        };
        let (x, y) = (block_summary(original, a), block_summary(converted, b));
        if a.name != b.name || x != y {
            out.push(Loss {
                setting,
                from: x,
                to: format!("{:?}: {y}", b.name),
            });
            continue;
        }
        let (p, q) = (a.source.as_ref(), b.source.as_ref());
        if p.map(settings_of) != q.map(settings_of) {
            let says = |s: Option<&serde_json::Value>| {
                match s {
                    Some(_) => "its QGroundControl complex item",
                    None => "none",
                }
                .to_string()
            };
            out.push(Loss {
                setting: format!("{setting} complex item"),
                from: says(p),
                to: if p.is_some() && q.is_some() {
                    "changed settings".into()
                } else {
                    says(q)
                },
            });
        }
    }
    for b in converted.blocks.iter().skip(original.blocks.len()) {
        out.push(Loss {
            setting: format!("block {:?}", b.name),
            from: "none".into(),
            to: block_summary(converted, b),
        });
    }
}

/// The fence's zones (in the order the formats write them: polygons, then circles), its
/// breach return point and the rally points, compared in the original's local frame.
fn fence_losses(out: &mut Vec<Loss>, original: &Mission, converted: &Mission) {
    let origin = &original.origin;
    let ordered = |m: &Mission| {
        let (polygons, circles): (Vec<_>, Vec<_>) = m
            .fence
            .zones
            .iter()
            .cloned()
            .partition(|z| matches!(z.shape, Shape::Polygon(_)));
        polygons.into_iter().chain(circles).collect::<Vec<_>>()
    };
    let (a, b) = (ordered(original), ordered(converted));
    let moved = |p: &LatLon, q: &LatLon| {
        let at = |l: &LatLon| {
            origin.to_enu(Geodetic {
                lat_deg: l.lat_deg,
                lon_deg: l.lon_deg,
                alt_m: origin.home.alt_m,
            })
        };
        let (p, q) = (at(p), at(q));
        (p.x_east_m - q.x_east_m).hypot(p.y_north_m - q.y_north_m)
    };
    for (k, (z, y)) in a.iter().zip(&b).enumerate() {
        let what = z.describe(k + 1);
        if z.inclusion != y.inclusion
            || std::mem::discriminant(&z.shape) != std::mem::discriminant(&y.shape)
        {
            out.push(Loss {
                setting: format!("fence zone {}", k + 1),
                from: what.clone(),
                to: y.describe(k + 1),
            });
            continue;
        }
        match (&z.shape, &y.shape) {
            (Shape::Polygon(p), Shape::Polygon(q)) => {
                if p.len() != q.len() {
                    out.push(Loss {
                        setting: format!("{what} vertices (count)"),
                        from: p.len().to_string(),
                        to: q.len().to_string(),
                    });
                    continue;
                }
                for (i, (u, v)) in p.iter().zip(q).enumerate() {
                    number(
                        out,
                        format!("{what} vertex {} (moved, m)", i + 1),
                        0.0,
                        moved(u, v),
                        POSITION_TOLERANCE_M,
                    );
                }
            }
            (
                Shape::Circle {
                    center: c,
                    radius_m: r,
                },
                Shape::Circle {
                    center: d,
                    radius_m: s,
                },
            ) => {
                number(
                    out,
                    format!("{what} center (moved, m)"),
                    0.0,
                    moved(c, d),
                    POSITION_TOLERANCE_M,
                );
                number(
                    out,
                    format!("{what} radius_m"),
                    *r,
                    *s,
                    POSITION_TOLERANCE_M,
                );
            }
            _ => {}
        }
    }
    if a.len() != b.len() {
        out.push(Loss {
            setting: "fence zones (count)".into(),
            from: a.len().to_string(),
            to: b.len().to_string(),
        });
    }
    let local = |m: &Mission, g: Geodetic| {
        origin.to_enu(Geodetic {
            alt_m: m.origin.home.alt_m + g.alt_m,
            ..g
        })
    };
    let distance = |p: super::Enu, q: super::Enu| {
        ((p.x_east_m - q.x_east_m).powi(2)
            + (p.y_north_m - q.y_north_m).powi(2)
            + (p.z_up_m - q.z_up_m).powi(2))
        .sqrt()
    };
    match (original.fence.breach_return, converted.fence.breach_return) {
        (Some(p), Some(q)) => number(
            out,
            "fence breach_return (moved, m)".into(),
            0.0,
            distance(local(original, p), local(converted, q)),
            POSITION_TOLERANCE_M,
        ),
        (None, None) => {}
        (p, q) => out.push(Loss {
            setting: "fence breach_return".into(),
            from: if p.is_some() { "a point" } else { "none" }.into(),
            to: if q.is_some() { "a point" } else { "none" }.into(),
        }),
    }
    let rally_point = |m: &Mission, r: &RallyPoint| {
        local(
            m,
            Geodetic {
                lat_deg: r.lat_deg,
                lon_deg: r.lon_deg,
                alt_m: r.alt_above_home_m,
            },
        )
    };
    for (k, (r, s)) in original.rally.iter().zip(&converted.rally).enumerate() {
        number(
            out,
            format!("rally point {} (moved, m)", k + 1),
            0.0,
            distance(rally_point(original, r), rally_point(converted, s)),
            POSITION_TOLERANCE_M,
        );
    }
    if original.rally.len() != converted.rally.len() {
        out.push(Loss {
            setting: "rally points (count)".into(),
            from: original.rally.len().to_string(),
            to: converted.rally.len().to_string(),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(file: &str) -> Mission {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("missions")
            .join(file);
        super::super::load(&path).unwrap()
    }

    #[test]
    fn a_mission_converted_to_its_own_format_loses_nothing() {
        let m = sample("paper-sample-8wp.toml");
        let (_, losses) = convert(&m, Path::new("paper-sample-8wp.toml")).unwrap();
        assert_eq!(losses, vec![]);
    }

    #[test]
    fn waypoints_drop_the_minimum_height_and_the_default_hover_and_say_their_values() {
        let mut m = sample("paper-sample-8wp.toml");
        m.min_height_above_home_m = 5.0;
        m.default_hover_s = 8.0;
        let (_, losses) = convert(&m, Path::new("paper-sample-8wp.waypoints")).unwrap();
        let said: Vec<String> = losses.iter().map(Loss::to_string).collect();
        assert!(
            said.contains(&"min_height_above_home_m: 5 -> 2".to_string()),
            "{said:?}"
        );
        assert!(
            said.contains(&"default_hover_s: 8 -> 0".to_string()),
            "{said:?}"
        );
    }

    #[test]
    fn every_shipped_mission_round_trips_through_every_format_or_names_what_it_loses() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("missions");
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        assert!(files.len() >= 6);
        for file in files {
            let m = super::super::load(&file).unwrap();
            let stem = file.file_stem().unwrap().to_str().unwrap().to_string();
            for ext in ["toml", "plan", "waypoints"] {
                let out = Path::new("/converted").join(format!("{stem}.{ext}"));
                if ext == "waypoints" && m.cannot_be_wpl("").is_some() {
                    // A fence or rally points: refused, naming the file and what it would lose.
                    let refused = convert(&m, &out).unwrap_err().to_string();
                    assert!(
                        refused.starts_with(&format!("{}: a .waypoints file", out.display()))
                            && refused.contains("nothing written"),
                        "{refused}"
                    );
                    continue;
                }
                let (text, lost) = convert(&m, &out).unwrap();
                let there = load_str(&text, Format::from_path(&out).unwrap(), Some(&out)).unwrap();
                if ext == "waypoints" {
                    // QGC WPL 110 holds no names, default hover or minimum height: only those
                    // may be lost, and positions and hover times survive.
                    for l in &lost {
                        assert!(
                            l.setting.ends_with(" name")
                                || l.setting.starts_with("block ")
                                || l.setting == "default_hover_s"
                                || l.setting == "min_height_above_home_m",
                            "{}: {l}",
                            file.display()
                        );
                    }
                } else {
                    assert_eq!(lost, vec![], "{} -> {ext}", file.display());
                }
                // And back to the format it came from: nothing more is lost.
                let (_, back) = convert(&there, &file).unwrap();
                let (_, direct) = convert(&m, &file).unwrap();
                assert_eq!(back, vec![], "{} -> {ext} -> back", file.display());
                assert_eq!(direct, vec![], "{}", file.display());
            }
        }
    }

    #[test]
    fn a_renamed_or_moved_waypoint_is_a_loss_naming_it() {
        let m = sample("paper-sample-3wp.toml");
        let mut other = m.clone();
        other.waypoints[1].position.z_up_m += 0.5;
        other.waypoints[2].hover_s += 1.0;
        let said: Vec<String> = losses(&m, &other).iter().map(Loss::to_string).collect();
        let (b, c) = (&m.waypoints[1].name, &m.waypoints[2].name);
        assert_eq!(said.len(), 2, "{said:?}");
        assert!(said[0].starts_with(&format!("waypoint {b} position (moved, m): 0 -> 0.5")));
        assert!(said[1].starts_with(&format!("waypoint {c} hover_s")));
    }
}
