//! SVG figures drawn with plotters: the orders of a planned mission as the paper draws them (a
//! top view and two side views, the energy order solid and the min-distance order dashed, with
//! arrows giving the direction of flight), histograms of the random-mission study's
//! baseline/minimum-energy energy ratios, and each pack's capacity and internal resistance over
//! its cycles (`emplan packs --plot`). A mission's geofence is drawn in the top view (an
//! inclusion zone outlined in green, an exclusion zone filled in red) and its rally points in
//! every view (a purple cross, `R1`, `R2`, ...). A block (a survey's or scan's lines) is drawn as
//! one wide teal path under the orders, its entry and exit in the energy order marked and the
//! block labelled with its name and that direction; the orders' lines are its connecting legs.
//!
//! Figures are rendered into a string: the command line writes it to a file once (so a write
//! error is reported with the file name and never lost in a drop), the service answers it as
//! `image/svg+xml` (`/api/missions/{name}/plot.svg`, `/api/flights/{name}/plot.svg`) for the
//! dashboard.

use crate::mission::fence::LocalShape;
use crate::mission::{Enu, Mission};
use crate::physics::Profile;
use crate::planner::explain::saving_words;
use crate::planner::json::energy_kj;
use crate::planner::study::{BaselineDirection, Study, BASELINES};
use crate::planner::{Order, Plan};
use crate::tour::Objective;
use plotters::coord::types::RangedCoordf64;
use plotters::element::DashedPathElement;
use plotters::prelude::*;

const FONT: &str = "sans-serif";
const ENERGY_COLOUR: RGBColor = RGBColor(0x1f, 0x5f, 0xbf);
const DISTANCE_COLOUR: RGBColor = RGBColor(0xd6, 0x4b, 0x1c);
const INCLUSION_COLOUR: RGBColor = RGBColor(0x2e, 0x8b, 0x57);
const EXCLUSION_COLOUR: RGBColor = RGBColor(0xc0, 0x1c, 0x28);
const RALLY_COLOUR: RGBColor = RGBColor(0x81, 0x3d, 0x9c);
const BLOCK_COLOUR: RGBColor = RGBColor(0x00, 0x89, 0x7b);
/// Stroke width of a block's lines (the orders' connecting legs are 2).
const BLOCK_STROKE_PX: u32 = 6;
/// Straight sides a fence circle is drawn with.
const CIRCLE_SIDES: usize = 72;
const WIDTH_PX: u32 = 1800;
const HEIGHT_PX: u32 = 720;

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("plotting {mission}: no {order} order to draw")]
    NoOrder {
        mission: String,
        order: &'static str,
    },
    #[error("drawing {figure}: {reason}")]
    Drawing { figure: String, reason: String },
}

fn drawing<E: std::fmt::Display>(figure: &str) -> impl Fn(E) -> PlotError + '_ {
    move |e| PlotError::Drawing {
        figure: figure.to_string(),
        reason: e.to_string(),
    }
}

/// One projection of the mission: which coordinates go on which axis.
struct View {
    caption: &'static str,
    x_desc: &'static str,
    y_desc: &'static str,
    project: fn(&Enu) -> (f64, f64),
}

const VIEWS: [View; 3] = [
    View {
        caption: "top view",
        x_desc: "x east (m)",
        y_desc: "y north (m)",
        project: |p| (p.x_east_m, p.y_north_m),
    },
    View {
        caption: "side view from the south",
        x_desc: "x east (m)",
        y_desc: "z up (m)",
        project: |p| (p.x_east_m, p.z_up_m),
    },
    View {
        caption: "side view from the east",
        x_desc: "y north (m)",
        y_desc: "z up (m)",
        project: |p| (p.y_north_m, p.z_up_m),
    },
];

/// A padded symmetric or spanning range that never collapses to a point.
fn span(values: impl Iterator<Item = f64> + Clone, symmetric: bool) -> std::ops::Range<f64> {
    let lo = values.clone().fold(0.0_f64, f64::min);
    let hi = values.fold(0.0_f64, f64::max);
    if symmetric {
        let r = lo.abs().max(hi.abs()).max(1.0) * 1.12;
        -r..r
    } else {
        let pad = ((hi - lo) * 0.12).max(1.0);
        lo - pad..hi + pad
    }
}

/// Draws the orders of `plan` of `mission` as an SVG document: top view (x-y) and side views (x-z,
/// y-z) of the origin and the named waypoints, the energy order solid, the min-distance order in
/// its better direction dashed.
pub fn plan_svg(mission: &Mission, plan: &Plan) -> Result<String, PlotError> {
    let profile = plan.profile;
    let no_order = |order| PlotError::NoOrder {
        mission: mission.name.clone(),
        order,
    };
    let energy = plan
        .order(Objective::Energy)
        .ok_or_else(|| no_order("energy"))?;
    let distance = plan
        .cheapest(Objective::Distance)
        .ok_or_else(|| no_order("distance"))?;
    let e_kj = energy_kj(&energy.legs);
    let d_kj = energy_kj(&distance.legs);
    let direction = format!("{:?}", distance.direction).to_lowercase();

    // Node 0 is the origin, node k the k-th waypoint of the file.
    let points: Vec<Enu> = std::iter::once(Enu::default())
        .chain(mission.waypoints.iter().map(|w| w.position))
        .collect();
    let names: Vec<&str> = std::iter::once("origin")
        .chain(mission.waypoints.iter().map(|w| w.name.as_str()))
        .collect();
    let closed = |nodes: &[usize]| -> Vec<usize> {
        std::iter::once(0)
            .chain(nodes.iter().copied())
            .chain(std::iter::once(0))
            .collect()
    };
    let energy_path = closed(&energy.nodes);
    let distance_path = closed(&distance.nodes);
    // The legs inside a block are its lines, drawn as the block; the orders draw the rest.
    let energy_runs = connecting_runs(mission, &energy_path);
    let distance_runs = connecting_runs(mission, &distance_path);
    let blocks: Vec<DrawnBlock> = (0..mission.blocks.len())
        .map(|b| DrawnBlock::of(mission, energy, b))
        .collect();

    // The fence's zones as closed outlines (east, north) and the rally points, in the local frame.
    let zones: Vec<(bool, Vec<(f64, f64)>)> = mission
        .fence
        .zones
        .iter()
        .map(|z| {
            let local = z.local(&mission.origin);
            let outline = match &local.shape {
                LocalShape::Polygon(v) => v.iter().map(|p| (p[0], p[1])).collect(),
                LocalShape::Circle { center, radius_m } => (0..CIRCLE_SIDES)
                    .map(|k| {
                        let a = std::f64::consts::TAU * k as f64 / CIRCLE_SIDES as f64;
                        (
                            center[0] + radius_m * a.cos(),
                            center[1] + radius_m * a.sin(),
                        )
                    })
                    .collect(),
            };
            (z.inclusion, outline)
        })
        .collect();
    let rally: Vec<Enu> = mission
        .rally
        .iter()
        .map(|r| r.local(&mission.origin))
        .collect();

    let horizontal = span(
        points
            .iter()
            .chain(&rally)
            .flat_map(|p| [p.x_east_m, p.y_north_m])
            .chain(
                zones
                    .iter()
                    .flat_map(|(_, o)| o.iter().flat_map(|p| [p.0, p.1])),
            ),
        true,
    );
    let vertical = span(points.iter().chain(&rally).map(|p| p.z_up_m), false);

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH_PX, HEIGHT_PX)).into_drawing_area();
        let err = drawing("the orders of the mission");
        root.fill(&WHITE).map_err(&err)?;
        let (header, body) = root.split_vertically(96);
        let title = format!(
            "{}: minimum-energy order {e_kj:.2} kJ, minimum-distance order ({direction}) {d_kj:.2} kJ; \
             the energy order {}; {profile} profile",
            mission.name,
            saving_words(energy.energy_j, distance.energy_j)
        );
        let sequence = |o: &Order| {
            // A block is named once, with its direction in this order.
            let mut words = vec!["origin".to_string()];
            let mut last_block = None;
            for &n in &o.nodes {
                match mission.block_of(n - 1) {
                    Some(b) if last_block == Some(b) => {}
                    Some(b) => {
                        words.push(format!(
                            "{} ({})",
                            mission.blocks[b].name,
                            direction_word(flown_reversed(mission, o, b))
                        ));
                        last_block = Some(b);
                    }
                    None => {
                        words.push(plan.name(n).to_string());
                        last_block = None;
                    }
                }
            }
            words.push("origin".to_string());
            words.join(" > ")
        };
        header
            .draw(&Text::new(title, (20, 14), (FONT, 24).into_font()))
            .map_err(&err)?;
        // The legend: a line sample in each order's style, then its energy and sequence.
        header
            .draw(&PathElement::new(
                vec![(24, 55), (64, 55)],
                ENERGY_COLOUR.stroke_width(2),
            ))
            .map_err(&err)?;
        header
            .draw(&Text::new(
                format!("minimum energy, {e_kj:.2} kJ: {}", sequence(energy)),
                (76, 46),
                (FONT, 17).into_font().color(&ENERGY_COLOUR),
            ))
            .map_err(&err)?;
        header
            .draw(&DashedPathElement::new(
                vec![(24, 79), (64, 79)],
                8,
                6,
                DISTANCE_COLOUR.stroke_width(2),
            ))
            .map_err(&err)?;
        header
            .draw(&Text::new(
                format!(
                    "minimum distance, {direction}, {d_kj:.2} kJ: {}",
                    sequence(distance)
                ),
                (76, 70),
                (FONT, 17).into_font().color(&DISTANCE_COLOUR),
            ))
            .map_err(&err)?;
        for (k, (panel, view)) in body.split_evenly((1, 3)).iter().zip(&VIEWS).enumerate() {
            let y_range = if k == 0 {
                horizontal.clone()
            } else {
                vertical.clone()
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(view.caption, (FONT, 20))
                .margin(14)
                .x_label_area_size(44)
                .y_label_area_size(56)
                .build_cartesian_2d(horizontal.clone(), y_range)
                .map_err(&err)?;
            chart
                .configure_mesh()
                .x_desc(view.x_desc)
                .y_desc(view.y_desc)
                .light_line_style(RGBColor(0xee, 0xee, 0xee))
                .draw()
                .map_err(&err)?;
            let at = |node: usize| (view.project)(&points[node]);
            if k == 0 {
                for (inclusion, outline) in &zones {
                    let colour = if *inclusion {
                        INCLUSION_COLOUR
                    } else {
                        EXCLUSION_COLOUR
                    };
                    if !*inclusion {
                        chart
                            .draw_series(std::iter::once(Polygon::new(
                                outline.clone(),
                                colour.mix(0.25).filled(),
                            )))
                            .map_err(&err)?;
                    }
                    let closed: Vec<(f64, f64)> =
                        outline.iter().chain(outline.first()).copied().collect();
                    chart
                        .draw_series(std::iter::once(PathElement::new(
                            closed,
                            colour.stroke_width(2),
                        )))
                        .map_err(&err)?;
                }
            }

            for block in &blocks {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        block.nodes.iter().map(|&n| at(n)).collect::<Vec<_>>(),
                        BLOCK_COLOUR.mix(0.6).stroke_width(BLOCK_STROKE_PX),
                    )))
                    .map_err(&err)?;
            }
            for run in &energy_runs {
                chart
                    .draw_series(LineSeries::new(
                        run.iter().map(|&n| at(n)),
                        ENERGY_COLOUR.stroke_width(2),
                    ))
                    .map_err(&err)?;
            }
            for run in &distance_runs {
                chart
                    .draw_series(DashedLineSeries::new(
                        run.iter().map(|&n| at(n)),
                        8,
                        6,
                        DISTANCE_COLOUR.stroke_width(2),
                    ))
                    .map_err(&err)?;
            }
            for (path_nodes, colour, along) in [
                (&energy_path, ENERGY_COLOUR, 0.55),
                (&distance_path, DISTANCE_COLOUR, 0.45),
            ] {
                let arrows: Vec<_> = path_nodes
                    .windows(2)
                    .filter(|w| !inner_leg(mission, w[0], w[1]))
                    .filter_map(|w| arrow(&chart, at(w[0]), at(w[1]), along))
                    .collect();
                chart
                    .draw_series(arrows.into_iter().map(|a| {
                        EmptyElement::at(a.anchor) + Polygon::new(a.corners_px, colour.filled())
                    }))
                    .map_err(&err)?;
            }
            chart
                .draw_series(points.iter().enumerate().map(|(node, p)| {
                    let marker: DynElement<_, _> = if node == 0 {
                        TriangleMarker::new((0, 0), 7, BLACK.filled()).into_dyn()
                    } else {
                        Circle::new((0, 0), 4, BLACK.filled()).into_dyn()
                    };
                    // A block's waypoints are named by the block's label.
                    let name = if node > 0 && mission.block_of(node - 1).is_some() {
                        ""
                    } else {
                        names[node]
                    };
                    EmptyElement::at((view.project)(p))
                        + marker
                        + Text::new(name.to_string(), (7, -18), (FONT, 15))
                }))
                .map_err(&err)?;
            for block in &blocks {
                let mark = |node: usize, word: &'static str, filled: bool| {
                    let style = if filled {
                        BLOCK_COLOUR.filled()
                    } else {
                        BLOCK_COLOUR.stroke_width(2)
                    };
                    EmptyElement::at(at(node))
                        + Rectangle::new([(-7, -7), (7, 7)], style)
                        + Text::new(word, (10, 4), (FONT, 14).into_font().color(&BLOCK_COLOUR))
                };
                chart
                    .draw_series([
                        mark(block.entry, "entry", true),
                        mark(block.exit, "exit", false),
                    ])
                    .map_err(&err)?;
                chart
                    .draw_series(std::iter::once(
                        EmptyElement::at(block.label_at(&points, view.project))
                            + Text::new(
                                block.label.clone(),
                                (-30, -30),
                                (FONT, 16).into_font().color(&BLOCK_COLOUR),
                            ),
                    ))
                    .map_err(&err)?;
            }
            if rally.is_empty() {
                continue;
            }
            chart
                .draw_series(rally.iter().enumerate().map(|(k, p)| {
                    EmptyElement::at((view.project)(p))
                        + Cross::new((0, 0), 6, RALLY_COLOUR.stroke_width(2))
                        + Text::new(
                            format!("R{}", k + 1),
                            (7, -18),
                            (FONT, 15).into_font().color(&RALLY_COLOUR),
                        )
                }))
                .map_err(&err)?;
        }
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

/// A block as the figure draws it: its nodes in file order (its lines), where the energy order
/// enters and leaves it, and its label (name, kind, that direction).
struct DrawnBlock {
    nodes: Vec<usize>,
    entry: usize,
    exit: usize,
    label: String,
}

impl DrawnBlock {
    fn of(mission: &Mission, energy: &Order, b: usize) -> DrawnBlock {
        let block = &mission.blocks[b];
        let reversed = flown_reversed(mission, energy, b);
        DrawnBlock {
            nodes: block.waypoints().map(|k| k + 1).collect(),
            entry: block.entry(reversed) + 1,
            exit: block.exit(reversed) + 1,
            label: format!(
                "{}: {}, {}",
                block.name,
                block.kind.word(),
                direction_word(reversed)
            ),
        }
    }

    /// Where its label goes in a view: the middle of its waypoints.
    fn label_at(&self, points: &[Enu], project: fn(&Enu) -> (f64, f64)) -> (f64, f64) {
        let n = self.nodes.len().max(1) as f64;
        let (x, y) = self.nodes.iter().fold((0.0, 0.0), |(x, y), &k| {
            let (px, py) = project(&points[k]);
            (x + px, y + py)
        });
        (x / n, y / n)
    }
}

fn direction_word(reversed: bool) -> &'static str {
    if reversed {
        "reversed"
    } else {
        "forward"
    }
}

/// Whether `order` flies block `b` reversed: as the order says, else as its nodes show (its last
/// waypoint visited before its first).
fn flown_reversed(mission: &Mission, order: &Order, b: usize) -> bool {
    if let Some(f) = order.blocks.iter().find(|f| f.block == b) {
        return f.reversed;
    }
    let block = &mission.blocks[b];
    let at = |k: usize| order.nodes.iter().position(|&n| n == k + 1);
    matches!(
        (at(block.entry(false)), at(block.exit(false))),
        (Some(first), Some(last)) if last < first
    )
}

/// Whether the leg between nodes `a` and `b` is one of a block's own lines (two neighbouring
/// waypoints of the same block).
fn inner_leg(mission: &Mission, a: usize, b: usize) -> bool {
    a > 0
        && b > 0
        && a.abs_diff(b) == 1
        && mission
            .block_of(a - 1)
            .is_some_and(|block| mission.block_of(b - 1) == Some(block))
}

/// A closed path cut where it flies a block's lines: the runs of connecting legs (the whole path
/// for a mission without blocks).
fn connecting_runs(mission: &Mission, path: &[usize]) -> Vec<Vec<usize>> {
    let mut runs = Vec::new();
    let mut run: Vec<usize> = path.first().copied().into_iter().collect();
    for w in path.windows(2) {
        if inner_leg(mission, w[0], w[1]) {
            if run.len() > 1 {
                runs.push(std::mem::take(&mut run));
            }
            run = vec![w[1]];
        } else {
            run.push(w[1]);
        }
    }
    if run.len() > 1 {
        runs.push(run);
    }
    runs
}

/// An arrowhead: its anchor in data coordinates and its corners in pixels around the anchor.
struct Arrowhead {
    anchor: (f64, f64),
    corners_px: Vec<(i32, i32)>,
}

/// A small arrowhead at fraction `along` of the leg `from -> to`, pointing the way the leg is
/// flown, drawn in screen space so unequal axis scales do not distort it; none for legs a few
/// pixels long in this view.
fn arrow<'a>(
    chart: &ChartContext<'a, SVGBackend<'a>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    from: (f64, f64),
    to: (f64, f64),
    along: f64,
) -> Option<Arrowhead> {
    let (a, b) = (chart.backend_coord(&from), chart.backend_coord(&to));
    let (dx, dy) = (f64::from(b.0 - a.0), f64::from(b.1 - a.1));
    let len = dx.hypot(dy);
    if len < 24.0 {
        return None;
    }
    let (ux, uy) = (dx / len, dy / len);
    let px = |fwd: f64, side: f64| {
        (
            (ux * fwd - uy * side).round() as i32,
            (uy * fwd + ux * side).round() as i32,
        )
    };
    let anchor = (
        from.0 + along * (to.0 - from.0),
        from.1 + along * (to.1 - from.1),
    );
    Some(Arrowhead {
        anchor,
        corners_px: vec![px(7.0, 0.0), px(-5.0, 5.0), px(-5.0, -5.0)],
    })
}

fn baseline_label(baseline: Objective) -> &'static str {
    match baseline {
        Objective::Distance => "min-D (3D distance)",
        Objective::Horizontal => "min-X (horizontal distance)",
        Objective::Vertical => "min-Z (vertical distance, ties by horizontal)",
        Objective::Energy => "min energy",
    }
}

/// Histograms of the energy ratio baseline / minimum energy over the study's missions, one
/// panel per baseline (in the study's direction: its better one or the solver's), sharing the
/// ratio axis.
pub fn study_histogram_svg(study: &Study, profile: Profile) -> Result<String, PlotError> {
    const BINS: usize = 40;
    let s = &study.settings;
    let max_ratio = study
        .outcomes
        .iter()
        .flat_map(|o| BASELINES.map(|b| o.ratio(b)))
        .fold(1.0_f64, f64::max);
    let width = ((max_ratio - 1.0) / BINS as f64).max(1e-4);
    let x_range = 1.0..1.0 + width * BINS as f64;

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1100, 1000)).into_drawing_area();
        let err = drawing("the study histogram");
        root.fill(&WHITE).map_err(&err)?;
        let root = root
            .titled(
                &format!(
                    "baseline energy ({} direction) / minimum energy: {} missions, {} \
                     waypoints in ±{} x ±{} x ±{} m, seed {}, {profile}",
                    match study.direction {
                        BaselineDirection::Better => "better",
                        BaselineDirection::Solver => "solver's",
                    },
                    study.outcomes.len(),
                    s.waypoints,
                    s.xy_m,
                    s.xy_m,
                    s.z_m,
                    s.seed
                ),
                (FONT, 20),
            )
            .map_err(&err)?;
        let stats = [
            study.summary.distance,
            study.summary.horizontal,
            study.summary.vertical,
        ];
        for ((panel, baseline), st) in root.split_evenly((3, 1)).iter().zip(BASELINES).zip(stats) {
            let mut counts = [0u32; BINS];
            for o in &study.outcomes {
                let bin = ((o.ratio(baseline) - 1.0) / width).floor() as usize;
                counts[bin.min(BINS - 1)] += 1;
            }
            let differs = if baseline == Objective::Distance {
                format!(
                    ", order differs from min-energy in {:.1}%",
                    study.summary.distance_differs_pct
                )
            } else {
                String::new()
            };
            let top = f64::from(counts.iter().copied().max().unwrap_or(1).max(1)) * 1.1;
            let mut chart = ChartBuilder::on(panel)
                .caption(
                    format!(
                        "{}: mean +{:.2}%, p90 +{:.2}%, max +{:.2}%{differs}",
                        baseline_label(baseline),
                        st.mean_pct,
                        st.p90_pct,
                        st.max_pct
                    ),
                    (FONT, 18),
                )
                .margin(12)
                .x_label_area_size(44)
                .y_label_area_size(64)
                .build_cartesian_2d(x_range.clone(), 0.0..top)
                .map_err(&err)?;
            chart
                .configure_mesh()
                .x_desc("energy / minimum energy")
                .y_desc("missions")
                .y_label_formatter(&|v| format!("{v:.0}"))
                .light_line_style(RGBColor(0xee, 0xee, 0xee))
                .draw()
                .map_err(&err)?;
            chart
                .draw_series(
                    counts
                        .iter()
                        .enumerate()
                        .filter(|(_, &c)| c > 0)
                        .map(|(k, &c)| {
                            let x0 = 1.0 + width * k as f64;
                            Rectangle::new(
                                [(x0, 0.0), (x0 + width, f64::from(c))],
                                ENERGY_COLOUR.mix(0.75).filled(),
                            )
                        }),
                )
                .map_err(&err)?;
        }
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

/// A recorded flight (or several) drawn: battery power over vehicle time with every leg shaded
/// and named, and each leg's predicted against measured energy as paired bars.
pub fn flight_svg(analyses: &[crate::flightlog::replay::Analysis]) -> Result<String, PlotError> {
    use crate::flightlog::segment::SegmentKind;
    let mut svg = String::new();
    {
        let rows = analyses.len().max(1);
        let root =
            SVGBackend::with_string(&mut svg, (WIDTH_PX, 560 * rows as u32)).into_drawing_area();
        let err = drawing("the flight figure");
        root.fill(&WHITE).map_err(&err)?;
        for (area, analysis) in root.split_evenly((rows, 1)).iter().zip(analyses) {
            let (left, right) = area.split_horizontally(WIDTH_PX * 3 / 5);
            let power = analysis.segmenter.series().valid_power();
            let t_max = power.last().map_or(1.0, |p| p.0).max(1.0);
            let p_max = power.iter().map(|p| p.1).fold(100.0_f64, f64::max) * 1.1;
            let mut chart = ChartBuilder::on(&left)
                .caption(
                    format!("{}: battery power", analysis.report.flight),
                    (FONT, 20),
                )
                .margin(12)
                .x_label_area_size(44)
                .y_label_area_size(64)
                .build_cartesian_2d(0.0..t_max, 0.0..p_max)
                .map_err(&err)?;
            chart
                .configure_mesh()
                .x_desc("vehicle time (s)")
                .y_desc("power (W)")
                .light_line_style(RGBColor(0xee, 0xee, 0xee))
                .draw()
                .map_err(&err)?;
            for segment in analysis.segmenter.segments() {
                if let SegmentKind::Leg(k) = segment.kind {
                    let shade = if k % 2 == 0 { 0.10 } else { 0.18 };
                    chart
                        .draw_series(std::iter::once(Rectangle::new(
                            [(segment.start_s, 0.0), (segment.end_s, p_max)],
                            ENERGY_COLOUR.mix(shade).filled(),
                        )))
                        .map_err(&err)?;
                    let (_, to) = analysis.segmenter.plan().leg_names(k);
                    chart
                        .draw_series(std::iter::once(Text::new(
                            to,
                            (segment.start_s, p_max * 0.97),
                            (FONT, 14),
                        )))
                        .map_err(&err)?;
                }
            }
            chart
                .draw_series(LineSeries::new(
                    power.iter().copied(),
                    DISTANCE_COLOUR.stroke_width(2),
                ))
                .map_err(&err)?;
            // Predicted vs measured per leg.
            let legs = &analysis.report.legs;
            let top = legs
                .iter()
                .flat_map(|l| [l.predicted_j, l.measured_j])
                .flatten()
                .fold(1.0_f64, f64::max)
                / 1000.0
                * 1.15;
            let n = legs.len().max(1) as f64;
            let mut bars = ChartBuilder::on(&right)
                .caption(
                    "energy per leg: predicted (light) vs measured (dark)",
                    (FONT, 18),
                )
                .margin(12)
                .x_label_area_size(44)
                .y_label_area_size(64)
                .build_cartesian_2d(0.0..n, 0.0..top)
                .map_err(&err)?;
            bars.configure_mesh()
                .x_desc("leg")
                .y_desc("kJ")
                .x_labels(legs.len().max(1))
                .x_label_formatter(&|x| format!("{}", x.floor() as usize + 1))
                .light_line_style(RGBColor(0xee, 0xee, 0xee))
                .draw()
                .map_err(&err)?;
            for (k, leg) in legs.iter().enumerate() {
                let x = k as f64;
                if let Some(p) = leg.predicted_j {
                    bars.draw_series(std::iter::once(Rectangle::new(
                        [(x + 0.1, 0.0), (x + 0.48, p / 1000.0)],
                        ENERGY_COLOUR.mix(0.35).filled(),
                    )))
                    .map_err(&err)?;
                }
                if let Some(m) = leg.measured_j {
                    bars.draw_series(std::iter::once(Rectangle::new(
                        [(x + 0.52, 0.0), (x + 0.9, m / 1000.0)],
                        ENERGY_COLOUR.filled(),
                    )))
                    .map_err(&err)?;
                }
            }
        }
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::blocks::{Block, BlockKind};
    use crate::planner::{plan_mission, FlownBlock, PlanOptions, VehicleModel};

    fn repo(path: &str) -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
    }

    /// The polylines of an SVG drawn in `colour` `width` px wide, as their point counts.
    fn polylines(svg: &str, colour: RGBColor, width: u32) -> Vec<usize> {
        let (r, g, b) = (colour.0, colour.1, colour.2);
        let stroke = format!("stroke=\"#{r:02X}{g:02X}{b:02X}\" stroke-width=\"{width}\"");
        svg.split("<polyline")
            .skip(1)
            .filter(|p| p.contains(&stroke))
            .map(|p| {
                let points = p.split("points=\"").nth(1).unwrap_or("");
                points
                    .split('"')
                    .next()
                    .unwrap_or("")
                    .split_whitespace()
                    .count()
            })
            .collect()
    }

    #[test]
    fn a_block_is_drawn_as_its_own_path_with_its_entry_exit_and_direction_apart_from_the_legs() {
        let model = VehicleModel::load(&repo("models/s1000"), None).unwrap();
        let mut mission = crate::mission::load(&repo("missions/paper-sample-8wp.toml")).unwrap();
        // C, D and E as a survey's lines.
        mission.blocks = vec![Block {
            name: "S1".into(),
            kind: BlockKind::Survey,
            first: 2,
            len: 3,
            reversible: true,
            source: None,
        }];
        let mut plan = plan_mission(&mission, &model, &PlanOptions::default()).unwrap();
        let k = plan
            .orders
            .iter()
            .position(|o| o.objective == Some(Objective::Energy))
            .unwrap();
        // The energy order as the planner flies a block: whole, here reversed (E, D, C).
        plan.orders[k].nodes = vec![1, 2, 5, 4, 3, 6, 7, 8];
        plan.orders[k].blocks = vec![FlownBlock {
            block: 0,
            reversed: true,
        }];
        let svg = plan_svg(&mission, &plan).unwrap();
        // The block's lines: one wide path through its three waypoints in each of the 3 views.
        assert_eq!(polylines(&svg, BLOCK_COLOUR, BLOCK_STROKE_PX), vec![3; 3]);
        let texts = |text: &str| svg.lines().filter(|l| l.trim() == text).count();
        assert_eq!(texts("S1: survey, reversed"), 3, "{svg}");
        assert_eq!(texts("entry"), 3);
        assert_eq!(texts("exit"), 3);
        // The energy order's connecting legs: the legend's sample, then in every view the run
        // to the block's entry (origin, A, B, E) and the run from its exit (C, F, G, H, origin).
        assert_eq!(
            polylines(&svg, ENERGY_COLOUR, 2),
            vec![2, 4, 5, 4, 5, 4, 5],
            "{svg}"
        );
        assert!(svg
            .contains("origin &gt; A &gt; B &gt; S1 (reversed) &gt; F &gt; G &gt; H &gt; origin"));
    }

    #[test]
    fn without_blocks_each_order_is_one_path() {
        let model = VehicleModel::load(&repo("models/s1000"), None).unwrap();
        let mission = crate::mission::load(&repo("missions/paper-sample-8wp.toml")).unwrap();
        let plan = plan_mission(&mission, &model, &PlanOptions::default()).unwrap();
        let svg = plan_svg(&mission, &plan).unwrap();
        assert_eq!(polylines(&svg, ENERGY_COLOUR, 2), vec![2, 10, 10, 10]);
        assert!(polylines(&svg, BLOCK_COLOUR, BLOCK_STROKE_PX).is_empty());
        assert!(!svg.lines().any(|l| l.trim() == "entry"));
    }
}

/// One flight's pack fit, at the equivalent full cycles its pack had drawn before it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackPoint {
    pub cycles: f64,
    pub capacity_ah: f64,
    pub capacity_sd_ah: f64,
    pub internal_resistance_ohm: f64,
}

/// A pack's capacity trend over its cycles, as a straight line between two cycle counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackTrend {
    pub from_cycles: f64,
    pub to_cycles: f64,
    pub capacity_from_ah: f64,
    pub capacity_to_ah: f64,
}

/// One pack as `emplan packs --plot` draws it (built from the ledger by the session).
#[derive(Debug, Clone, PartialEq)]
pub struct PackHistory {
    pub name: String,
    pub label_capacity_ah: Option<f64>,
    pub points: Vec<PackPoint>,
    pub trend: Option<PackTrend>,
}

/// Colours of the packs, in turn.
const PACK_COLOURS: [RGBColor; 8] = [
    ENERGY_COLOUR,
    DISTANCE_COLOUR,
    INCLUSION_COLOUR,
    RALLY_COLOUR,
    BLOCK_COLOUR,
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x7f, 0x7f, 0x7f),
];

/// The packs drawn: each flight's fitted capacity (with its standard error as a bar) over the
/// pack's equivalent full cycles with the trend dashed and the label dotted, and beside it each
/// flight's internal resistance; one colour per pack, named in the legend.
pub fn packs_svg(packs: &[PackHistory]) -> Result<String, PlotError> {
    let err = drawing("the packs figure");
    let all = || packs.iter().flat_map(|p| p.points.iter());
    let max_cycles = all().map(|p| p.cycles).fold(0.0_f64, f64::max).max(1.0) * 1.08;
    let capacity_hi = all()
        .map(|p| p.capacity_ah + p.capacity_sd_ah)
        .chain(packs.iter().filter_map(|p| p.label_capacity_ah))
        .fold(1.0_f64, f64::max)
        * 1.1;
    let capacity_lo = all()
        .map(|p| p.capacity_ah - p.capacity_sd_ah)
        .fold(capacity_hi, f64::min)
        .max(0.0)
        * 0.9;
    let resistance_hi = all()
        .map(|p| p.internal_resistance_ohm * 1000.0)
        .fold(1.0_f64, f64::max)
        * 1.2;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH_PX, HEIGHT_PX)).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let (left, right) = root.split_horizontally(WIDTH_PX / 2);
        let mut capacity = ChartBuilder::on(&left)
            .caption("capacity fitted per flight", (FONT, 20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(0.0..max_cycles, capacity_lo..capacity_hi)
            .map_err(&err)?;
        capacity
            .configure_mesh()
            .x_desc("equivalent full cycles")
            .y_desc("capacity (Ah)")
            .light_line_style(RGBColor(0xee, 0xee, 0xee))
            .draw()
            .map_err(&err)?;
        let mut resistance = ChartBuilder::on(&right)
            .caption("internal resistance fitted per flight", (FONT, 20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(0.0..max_cycles, 0.0..resistance_hi)
            .map_err(&err)?;
        resistance
            .configure_mesh()
            .x_desc("equivalent full cycles")
            .y_desc("resistance (mOhm)")
            .light_line_style(RGBColor(0xee, 0xee, 0xee))
            .draw()
            .map_err(&err)?;
        for (k, pack) in packs.iter().enumerate() {
            let colour = PACK_COLOURS[k % PACK_COLOURS.len()];
            capacity
                .draw_series(pack.points.iter().map(|p| {
                    PathElement::new(
                        vec![
                            (p.cycles, p.capacity_ah - p.capacity_sd_ah),
                            (p.cycles, p.capacity_ah + p.capacity_sd_ah),
                        ],
                        colour.stroke_width(1),
                    )
                }))
                .map_err(&err)?;
            capacity
                .draw_series(
                    (pack.points.iter())
                        .map(|p| Circle::new((p.cycles, p.capacity_ah), 4, colour.filled())),
                )
                .map_err(&err)?
                .label(pack.name.clone())
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
            if let Some(t) = &pack.trend {
                capacity
                    .draw_series(std::iter::once(DashedPathElement::new(
                        vec![
                            (t.from_cycles, t.capacity_from_ah),
                            (t.to_cycles, t.capacity_to_ah),
                        ],
                        6,
                        4,
                        colour.stroke_width(2),
                    )))
                    .map_err(&err)?;
            }
            if let Some(label) = pack.label_capacity_ah {
                capacity
                    .draw_series(std::iter::once(DashedPathElement::new(
                        vec![(0.0, label), (max_cycles, label)],
                        2,
                        4,
                        colour.mix(0.5).stroke_width(1),
                    )))
                    .map_err(&err)?;
            }
            resistance
                .draw_series(pack.points.iter().map(|p| {
                    Circle::new(
                        (p.cycles, p.internal_resistance_ohm * 1000.0),
                        4,
                        colour.filled(),
                    )
                }))
                .map_err(&err)?;
        }
        capacity
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}
