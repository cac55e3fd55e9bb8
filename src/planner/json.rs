//! The JSON views of a [`Plan`] (the shapes of docs/json.md): the document `emplan plan --json`
//! prints and the planning fields of `emplan upload --json`. The CLI and the HTTP service
//! serialise these, so both print the same document. Energies become kJ here, and only here.
//!
//! A printed total is the sum of its printed parts: an order's `energy_kj` adds its legs'
//! `energy_kj`, the battery's `total_kj` adds take-off, legs, hovering and landing in kJ, and
//! `excess_kj` is `total_kj - budget_kj`. A sortie's energies are converted from its own J.

use serde::Serialize;

use super::{Flight, Leg, Order, Orders, Plan, Sorties};
use crate::mission::fence::{LatLon, LocalShape, Shape};
use crate::mission::{Geodetic, Mission, Origin};
use crate::physics::{Pricing, Profile};
use crate::tour::solver::Solver;
use crate::tour::sorties::Method;
use crate::tour::{Direction, Objective};

/// kJ of `j` joules.
pub fn kj(j: f64) -> f64 {
    j / 1000.0
}

/// An order's energy as printed: the sum of its legs' kJ.
pub fn energy_kj(legs: &[Leg]) -> f64 {
    legs.iter().map(|l| kj(l.energy_j())).sum()
}

/// `emplan plan --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanJson {
    pub mission: String,
    pub profile: Profile,
    /// What the orders' and legs' `energy_kj` count: "settled" (to settled hover) or "paper"
    /// (to the 4 m rule). The battery always counts everything.
    pub pricing: Pricing,
    pub orders: Vec<OrderJson>,
    pub battery: BatteryJson,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sorties: Option<SortiesJson>,
    /// With `--wind`: the wind, and beside the wind-aware energy order the order still air
    /// would choose, priced in that wind.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wind: Option<WindJson>,
    /// A mission with actions: those of the flown order, place by place, priced, and the
    /// commands inserted to keep the file's settings.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub actions: Vec<ActionsAtJson>,
    /// A mission with a fence or rally points: the autopilot's return from each waypoint.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub returns: Option<super::returns::ReturnsJson>,
    /// The mission's geofence (absent without one; [`mission_document`] fills it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fence: Option<FenceJson>,
    /// The mission's rally points (absent without any; [`mission_document`] fills them).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub rally_points: Vec<PointJson>,
    /// The mission's blocks in file order (absent without any).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub blocks: Vec<MissionBlockJson>,
    /// What the plan could not do as asked, or did otherwise, in words (absent: nothing).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

/// One block of the mission, as the file gives it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MissionBlockJson {
    pub name: String,
    /// "survey", "corridor", "structure" or "listed" (written by hand).
    pub kind: crate::mission::blocks::BlockKind,
    /// Whether it may be flown last waypoint first.
    pub reversible: bool,
    /// Its waypoints' names in file order.
    pub waypoints: Vec<String>,
}

/// One block as an order flies it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockJson {
    pub name: String,
    pub kind: crate::mission::blocks::BlockKind,
    /// Flown last waypoint first.
    pub reversed: bool,
    /// The waypoints it is entered at and left from.
    pub entry: String,
    pub exit: String,
    /// How many waypoints it has.
    pub waypoints: usize,
    /// Its lines (3D), from entry to exit.
    pub distance_m: f64,
    /// Its lines' energy and the turns at their ends (part of the order's `energy_kj`).
    pub energy_kj: f64,
    /// The holds at its waypoints (counted in the battery's `hover_kj`).
    pub hover_kj: f64,
    /// Its lines' duration.
    pub duration_s: f64,
    /// The energy order's blocks: what entering at the other end would add, the rest of the
    /// order as flown (absent for a block flown only as written, and on other orders).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub other_end_kj: Option<f64>,
}

/// The `"fence"` object: the zones in the fence's order and the breach return point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FenceJson {
    pub zones: Vec<ZoneJson>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub breach_return: Option<PointJson>,
}

/// One zone of the fence.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ZoneJson {
    /// How errors and reports name it: "exclusion polygon 2" (its 1-based place in `zones`).
    pub name: String,
    /// True: the vehicle must stay inside it; false: out of it.
    pub inclusion: bool,
    /// "polygon" or "circle".
    pub shape: &'static str,
    /// A polygon's vertices in order (the last joins the first).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub vertices: Vec<VertexJson>,
    /// A circle's centre.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub center: Option<VertexJson>,
    /// A circle's radius.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius_m: Option<f64>,
}

/// A point of a zone: geodetic and in the mission's local frame (east and north of the
/// origin, metres).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VertexJson {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub x_east_m: f64,
    pub y_north_m: f64,
}

/// A rally point or the breach return point: geodetic (altitude above home) and in the
/// mission's local frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PointJson {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_above_home_m: f64,
    pub x_east_m: f64,
    pub y_north_m: f64,
    pub z_up_m: f64,
}

/// The actions at one place of the flown order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ActionsAtJson {
    /// "start" or the waypoint's name.
    pub at: String,
    pub commands: Vec<ActionJson>,
    /// Inserted after them: what the file's order has in force on the way to the next place.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub inserted: Vec<InsertedJson>,
}

/// One command of a place.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ActionJson {
    pub command: u16,
    pub what: String,
    /// The hover it takes (a hold; a turn at the yaw rate); 0 where the autopilot does not wait.
    pub hold_s: f64,
    pub energy_kj: f64,
}

/// One inserted command.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InsertedJson {
    pub command: u16,
    pub what: String,
    /// The setting it restores ("speed", "region of interest", ...).
    pub restores: &'static str,
}

/// The `"wind"` object of `emplan plan --wind S@FROM --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WindJson {
    pub speed_m_s: f64,
    /// The direction it blows from, degrees clockwise from north.
    pub from_deg: f64,
    /// The still-air energy order, its legs priced in this wind (with the energy order asked
    /// for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub still_air_order: Option<OrderJson>,
    /// The still-air order's price in still air.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub still_air_order_calm_kj: Option<f64>,
    /// The still-air order's price in this wind less the wind-aware energy order's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saving_kj: Option<f64>,
    /// `saving_kj` as a share of the still-air order's price in this wind.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saving_pct: Option<f64>,
    /// Whether the wind changed the order (the same tour in either direction is not the same
    /// order: legs flown the other way cost differently).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub order_changed: Option<bool>,
}

/// One order (the ORDER object of docs/json.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OrderJson {
    /// "energy", "distance", "horizontal", "vertical", or "listed".
    pub objective: &'static str,
    pub direction: Direction,
    /// Waypoint names in visiting order, origin excluded.
    pub sequence: Vec<String>,
    pub distance_m: f64,
    pub horizontal_m: f64,
    pub vertical_m: f64,
    pub energy_kj: f64,
    /// The turns in hover the waypoints' yaw actions take in this order (part of
    /// `energy_kj`); absent without yaw actions.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub actions_kj: Option<f64>,
    pub legs: Vec<LegJson>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proof: Option<ProofJson>,
    /// The blocks in flown order (absent for a mission without blocks).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub blocks: Vec<BlockJson>,
}

/// One leg of an order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LegJson {
    pub from: String,
    pub to: String,
    pub horizontal_m: f64,
    pub vertical_m: f64,
    pub energy_kj: f64,
    /// The horizontal speed it is flown at when a DO_CHANGE_SPEED set one (absent: the
    /// vehicle's own).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub speed_m_s: Option<f64>,
    /// A leg routed round the fence: the points it passes through without a hold (absent on a
    /// straight leg).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub via: Vec<ViaJson>,
    /// The fence zones it goes round ("exclusion polygon 1"; absent on a straight leg).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub round: Vec<String>,
    /// What the detour adds to the straight line it replaces: metres (3D) and kJ (absent on a
    /// straight leg; the kJ also when the straight line cannot be priced).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detour_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detour_kj: Option<f64>,
    /// A line of a block: the block's name (absent on a connecting leg).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub block: Option<String>,
}

/// One point a leg passes through round a fence zone: geodetic (altitude above mean sea
/// level) and in the mission's local frame (east, north, up from the origin).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViaJson {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_amsl_m: f64,
    pub e_m: f64,
    pub n_m: f64,
    pub u_m: f64,
}

/// What the solver proved, in the objective's printed units (kJ for energy, metres for the
/// distance baselines).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProofJson {
    pub solver: Solver,
    pub optimal: bool,
    pub lower_bound: f64,
    pub gap_pct: f64,
    pub seconds: f64,
}

/// The flown order against the battery.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BatteryJson {
    pub takeoff_kj: f64,
    pub legs_kj: f64,
    pub hover_kj: f64,
    pub landing_kj: f64,
    pub total_kj: f64,
    pub budget_kj: f64,
    pub reserve_pct: f64,
    pub feasible: bool,
    /// Energy over the budget (0 when feasible).
    pub excess_kj: f64,
    /// With a pack named (`--pack`): its name, its capacity against its label that the budget
    /// is scaled by (the ledger's; absent: nothing learned, the label), the flights it was
    /// learned from, and the budget on the label.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pack: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub capacity_ratio: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pack_flights: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub label_budget_kj: Option<f64>,
}

impl BatteryJson {
    /// The check of a flight planned on pack `name` holding `capacity_ratio` of its label
    /// (the budget already scaled by it; None: nothing learned of it, the label's) as learned
    /// from `flights` flights.
    pub fn on_pack(self, name: &str, capacity_ratio: Option<f64>, flights: usize) -> BatteryJson {
        let ratio = capacity_ratio.filter(|r| r.is_finite() && *r > 0.0);
        BatteryJson {
            pack: Some(name.to_string()),
            capacity_ratio: ratio,
            pack_flights: Some(flights),
            label_budget_kj: Some(ratio.map_or(self.budget_kj, |r| self.budget_kj / r)),
            ..self
        }
    }
}

/// The `"sorties"` object of `emplan plan --sorties --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SortiesJson {
    /// Number of sorties, one battery each.
    pub batteries: usize,
    /// Energy of all sorties together.
    pub total_kj: f64,
    /// Whether the total is proven minimal (exact split).
    pub optimal: bool,
    pub method: Method,
    /// Energy one battery may spend on a sortie, after its reserve.
    pub budget_kj: f64,
    /// The whole mission flown as one tour (the flown order), for comparison.
    pub single_tour_kj: f64,
    pub sorties: Vec<SortieJson>,
}

/// One sortie: origin -> `sequence` -> origin on a fresh battery.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SortieJson {
    /// Waypoint names in flying order, origin excluded.
    pub sequence: Vec<String>,
    pub takeoff_kj: f64,
    pub legs_kj: f64,
    pub hover_kj: f64,
    pub landing_kj: f64,
    pub total_kj: f64,
    /// Share of the battery's budget this sortie uses.
    pub budget_pct: f64,
    pub legs: Vec<LegJson>,
}

/// The planning fields of `emplan upload --json` (the link's fields follow them).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct UploadPlanJson {
    pub mission: String,
    /// The order asked for ("energy", "distance" or "listed").
    pub order: Orders,
    /// The sortie flown (1-based), if one was chosen.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sortie: Option<usize>,
    /// Waypoint names in flying order, origin excluded.
    pub sequence: Vec<String>,
    pub predicted_mission_kj: f64,
    pub budget_kj: f64,
}

fn objective_name(objective: Option<Objective>) -> &'static str {
    match objective {
        Some(Objective::Energy) => "energy",
        Some(Objective::Distance) => "distance",
        Some(Objective::Horizontal) => "horizontal",
        Some(Objective::Vertical) => "vertical",
        None => "listed",
    }
}

fn sequence(plan: &Plan, nodes: &[usize]) -> Vec<String> {
    nodes.iter().map(|&n| plan.name(n).to_string()).collect()
}

fn legs(plan: &Plan, legs: &[Leg]) -> Vec<LegJson> {
    legs.iter()
        .map(|l| LegJson {
            from: plan.name(l.from).to_string(),
            to: plan.name(l.to).to_string(),
            horizontal_m: l.horizontal_m,
            vertical_m: l.vertical_m,
            energy_kj: kj(l.energy_j()),
            speed_m_s: plan.speeds_m_s.get(l.to).copied().flatten(),
            via: l
                .via
                .iter()
                .map(|&p| {
                    let g = plan.origin.to_geodetic(p);
                    ViaJson {
                        lat_deg: g.lat_deg,
                        lon_deg: g.lon_deg,
                        alt_amsl_m: g.alt_m,
                        e_m: p.x_east_m,
                        n_m: p.y_north_m,
                        u_m: p.z_up_m,
                    }
                })
                .collect(),
            round: l.detour.as_ref().map_or(Vec::new(), |d| {
                d.zones
                    .iter()
                    .map(|&z| plan.zones.get(z).cloned().unwrap_or_default())
                    .collect()
            }),
            detour_m: l
                .detour
                .as_ref()
                .map(|d| l.distance_m - d.straight_distance_m),
            detour_kj: l
                .detour
                .as_ref()
                .and_then(|d| d.straight_energy_j)
                .map(|straight_j| kj(l.energy_j() - straight_j)),
            block: l
                .block
                .and_then(|b| plan.blocks.get(b))
                .map(|b| b.name.clone()),
        })
        .collect()
}

/// The blocks an order flies, as printed: each block's lines from the order's legs.
fn blocks_json(plan: &Plan, order: &Order) -> Vec<BlockJson> {
    let explained = plan
        .explanation
        .as_ref()
        .filter(|_| {
            plan.cheapest(Objective::Energy)
                .is_some_and(|e| std::ptr::eq(e, order))
        })
        .map_or(&[][..], |e| &e.blocks[..]);
    order
        .blocks
        .iter()
        .filter_map(|f| {
            let block = plan.blocks.get(f.block)?;
            let lines: Vec<&Leg> = order
                .legs
                .iter()
                .filter(|l| l.block == Some(f.block))
                .collect();
            // The turns at its lines' ends: what its way's price adds to its lines'.
            let turns_j = plan.block_ways.get(f.block, f.reversed).map_or(0.0, |w| {
                w.inner_j
                    - w.legs
                        .iter()
                        .map(|l| l.predicted.priced_energy_j(plan.pricing))
                        .sum::<f64>()
            });
            Some(BlockJson {
                name: block.name.clone(),
                kind: block.kind,
                reversed: f.reversed,
                entry: plan.name(block.entry(f.reversed) + 1).to_string(),
                exit: plan.name(block.exit(f.reversed) + 1).to_string(),
                waypoints: block.len,
                distance_m: lines.iter().map(|l| l.distance_m).sum(),
                energy_kj: lines.iter().map(|l| kj(l.energy_j())).sum::<f64>() + kj(turns_j),
                hover_kj: block.waypoints().map(|k| kj(plan.hover_j(k))).sum(),
                duration_s: lines.iter().map(|l| l.duration_s()).sum(),
                other_end_kj: explained
                    .iter()
                    .find(|e| e.block == f.block)
                    .and_then(|e| e.other_end_j)
                    .map(kj),
            })
        })
        .collect()
}

/// One order as printed.
pub fn order_json(plan: &Plan, order: &Order) -> OrderJson {
    // The energy order's bound is in J, a baseline's in metres.
    let scale = if order.objective == Some(Objective::Energy) {
        1e-3
    } else {
        1.0
    };
    OrderJson {
        objective: match (order.objective, plan.asked) {
            // The file's own order beside the solved ones (a mission with blocks).
            (None, Orders::All) => "file",
            (objective, _) => objective_name(objective),
        },
        direction: order.direction,
        sequence: sequence(plan, &order.nodes),
        distance_m: order.distance_m,
        horizontal_m: order.horizontal_m,
        vertical_m: order.vertical_m,
        energy_kj: energy_kj(&order.legs) + kj(order.actions_j),
        actions_kj: (order.actions_j > 0.0).then(|| kj(order.actions_j)),
        legs: legs(plan, &order.legs),
        proof: order.proof.as_ref().map(|p| ProofJson {
            solver: p.solver,
            optimal: p.optimal,
            lower_bound: p.lower_bound * scale,
            gap_pct: p.gap_pct,
            seconds: p.seconds,
        }),
        blocks: blocks_json(plan, order),
    }
}

/// The flown order against the battery, as printed.
pub fn battery_json(plan: &Plan) -> BatteryJson {
    let b = &plan.battery;
    // Everything the battery pays for each leg, whatever the plan's pricing.
    let (takeoff_kj, legs_kj, hover_kj, landing_kj) = (
        kj(b.takeoff_j),
        plan.flown()
            .legs
            .iter()
            .map(|l| kj(l.settled_energy_j()))
            .sum::<f64>(),
        kj(b.hover_j),
        kj(b.landing_j),
    );
    let total_kj = takeoff_kj + legs_kj + hover_kj + landing_kj;
    let budget_kj = kj(b.usable_j);
    BatteryJson {
        takeoff_kj,
        legs_kj,
        hover_kj,
        landing_kj,
        total_kj,
        budget_kj,
        reserve_pct: b.reserve_pct,
        feasible: b.feasible,
        excess_kj: (total_kj - budget_kj).max(0.0),
        pack: None,
        capacity_ratio: None,
        pack_flights: None,
        label_budget_kj: None,
    }
}

/// The sorties as printed; `single_tour_kj` is the flown order's total.
pub fn sorties_json(plan: &Plan, sorties: &Sorties) -> SortiesJson {
    let usable_j = plan.budget.usable_j;
    SortiesJson {
        batteries: sorties.sorties.len(),
        total_kj: kj(sorties.total_j),
        optimal: sorties.optimal,
        method: sorties.method,
        budget_kj: kj(usable_j),
        single_tour_kj: battery_json(plan).total_kj,
        sorties: sorties
            .sorties
            .iter()
            .map(|s| SortieJson {
                sequence: sequence(plan, &s.nodes),
                takeoff_kj: kj(s.battery.takeoff_j),
                legs_kj: kj(s.battery.legs_j),
                hover_kj: kj(s.battery.hover_j),
                landing_kj: kj(s.battery.landing_j),
                total_kj: kj(s.battery.total_j),
                budget_pct: 100.0 * s.battery.total_j / usable_j,
                legs: legs(plan, &s.legs),
            })
            .collect(),
    }
}

/// `emplan plan --json`: every order, the battery check and the sorties (when split).
pub fn plan_document(plan: &Plan) -> PlanJson {
    PlanJson {
        mission: plan.mission.clone(),
        profile: plan.profile,
        pricing: plan.pricing,
        orders: plan.orders.iter().map(|o| order_json(plan, o)).collect(),
        battery: battery_json(plan),
        sorties: plan.sorties.as_ref().map(|s| sorties_json(plan, s)),
        wind: wind_json(plan),
        actions: actions_json(plan),
        returns: plan.returns.as_ref().map(super::returns::Returns::json),
        fence: None,
        rally_points: Vec::new(),
        blocks: plan
            .blocks
            .iter()
            .map(|b| MissionBlockJson {
                name: b.name.clone(),
                kind: b.kind,
                reversible: b.reversible,
                waypoints: b
                    .waypoints()
                    .map(|k| plan.name(k + 1).to_string())
                    .collect(),
            })
            .collect(),
        notes: plan.notes.clone(),
    }
}

/// `emplan plan --json` of `plan` made from `mission`: [`plan_document`] with the fence and
/// the rally points the mission carries.
pub fn mission_document(plan: &Plan, mission: &Mission) -> PlanJson {
    PlanJson {
        fence: fence_json(mission),
        rally_points: rally_json(mission),
        ..plan_document(plan)
    }
}

fn point_json(origin: &Origin, lat_deg: f64, lon_deg: f64, alt_above_home_m: f64) -> PointJson {
    let e = origin.to_enu(Geodetic {
        lat_deg,
        lon_deg,
        alt_m: origin.home.alt_m + alt_above_home_m,
    });
    PointJson {
        lat_deg,
        lon_deg,
        alt_above_home_m,
        x_east_m: e.x_east_m,
        y_north_m: e.y_north_m,
        z_up_m: e.z_up_m,
    }
}

/// The `"fence"` object: None for a mission without a fence.
pub fn fence_json(mission: &Mission) -> Option<FenceJson> {
    let fence = &mission.fence;
    if fence.is_empty() && fence.breach_return.is_none() {
        return None;
    }
    let origin = &mission.origin;
    let zones = fence
        .zones
        .iter()
        .enumerate()
        .map(|(k, zone)| {
            let local = zone.local(origin);
            let vertex = |p: &LatLon, xy: [f64; 2]| VertexJson {
                lat_deg: p.lat_deg,
                lon_deg: p.lon_deg,
                x_east_m: xy[0],
                y_north_m: xy[1],
            };
            let (shape, vertices, center, radius_m) = match (&zone.shape, &local.shape) {
                (Shape::Polygon(v), LocalShape::Polygon(xy)) => (
                    "polygon",
                    v.iter().zip(xy).map(|(p, xy)| vertex(p, *xy)).collect(),
                    None,
                    None,
                ),
                (Shape::Circle { center, radius_m }, LocalShape::Circle { center: xy, .. }) => (
                    "circle",
                    Vec::new(),
                    Some(vertex(center, *xy)),
                    Some(*radius_m),
                ),
                _ => ("polygon", Vec::new(), None, None),
            };
            ZoneJson {
                name: zone.describe(k + 1),
                inclusion: zone.inclusion,
                shape,
                vertices,
                center,
                radius_m,
            }
        })
        .collect();
    Some(FenceJson {
        zones,
        breach_return: fence
            .breach_return
            .map(|g| point_json(origin, g.lat_deg, g.lon_deg, g.alt_m)),
    })
}

/// The `"rally_points"` array: empty for a mission without rally points.
pub fn rally_json(mission: &Mission) -> Vec<PointJson> {
    mission
        .rally
        .iter()
        .map(|r| point_json(&mission.origin, r.lat_deg, r.lon_deg, r.alt_above_home_m))
        .collect()
}

/// The `"actions"` array: empty for a mission without actions.
pub fn actions_json(plan: &Plan) -> Vec<ActionsAtJson> {
    plan.actions
        .iter()
        .map(|at| ActionsAtJson {
            at: if at.node == 0 {
                "start".into()
            } else {
                plan.name(at.node).to_string()
            },
            commands: at
                .actions
                .iter()
                .map(|a| ActionJson {
                    command: a.command,
                    what: a.what.clone(),
                    hold_s: a.hold_s,
                    energy_kj: kj(a.energy_j),
                })
                .collect(),
            inserted: at
                .inserted
                .iter()
                .map(|(restores, command, what)| InsertedJson {
                    command: *command,
                    what: what.clone(),
                    restores,
                })
                .collect(),
        })
        .collect()
}

/// The `"wind"` object: None in still air. The saving is of the printed kJ.
pub fn wind_json(plan: &Plan) -> Option<WindJson> {
    if plan.wind.is_calm() {
        return None;
    }
    let still = plan.still_air.as_ref();
    let aware = plan.cheapest(Objective::Energy);
    let still_order = still.map(|s| order_json(plan, &s.order));
    let saving_kj = match (&still_order, aware) {
        (Some(s), Some(a)) => Some(s.energy_kj - (energy_kj(&a.legs) + kj(a.actions_j))),
        _ => None,
    };
    let saving_pct = match (&still_order, saving_kj) {
        (Some(s), Some(k)) if s.energy_kj > 0.0 => Some(100.0 * k / s.energy_kj),
        _ => None,
    };
    Some(WindJson {
        speed_m_s: plan.wind.speed_m_s,
        from_deg: plan.wind.from_deg,
        still_air_order_calm_kj: still.map(|s| kj(s.still_air_energy_j)),
        order_changed: match (still, aware) {
            (Some(s), Some(a)) => Some(s.order.nodes != a.nodes),
            _ => None,
        },
        still_air_order: still_order,
        saving_kj,
        saving_pct,
    })
}

/// The planning fields of `emplan upload --json` for `flight` of `plan`.
pub fn upload_document(plan: &Plan, flight: &Flight) -> UploadPlanJson {
    let predicted_mission_kj = match flight.sortie {
        Some(_) => kj(flight.battery.total_j),
        None => battery_json(plan).total_kj,
    };
    UploadPlanJson {
        mission: plan.mission.clone(),
        order: plan.asked,
        sortie: flight.sortie,
        sequence: sequence(plan, flight.nodes),
        predicted_mission_kj,
        budget_kj: kj(flight.battery.usable_j),
    }
}
