//! The planning pipeline as one library call: a mission and a vehicle model in, a [`Plan`] out
//! (every order asked for with each leg's predicted energy and duration, the battery check of
//! the order to fly, the sorties when asked, the solver's proof and where the energy order
//! saves). The CLI (`emplan plan`, `emplan upload`, `emplan fly`) and the HTTP service call
//! [`plan_mission`] and print [`json`]'s views of its result. [`study`] is the paper's
//! random-mission study, which prices its missions the same way.
//!
//! The planner sits above `physics` and `tour` and joins them: it prices legs with the vehicle's
//! energy table and hands `tour` the resulting cost matrix, so `tour` never imports `physics`.
//!
//! Node numbering, as in `tour`: node 0 is the origin, node `k + 1` is waypoint `k` of the
//! mission file. [`Order::waypoints`] and [`Flight::waypoints`] give 0-based waypoint indices,
//! what `link::items::mission_items` takes.
//!
//! Energies are in J here; [`json`] converts to kJ for output.
//!
//! A plan can be stopped from another thread: run [`plan_mission`] inside
//! [`crate::tour::cancel::within`] and raise the token; it then answers
//! [`PlannerError::Cancelled`] within milliseconds, whatever phase it was in.
//!
//! Invariant: pure; no IO, no tokio, no MAVLink.

pub mod blocks;
pub mod detour;
pub mod explain;
pub mod json;
pub mod returns;
pub mod study;

use serde::Serialize;

use crate::mission::actions::{yaw_s, Action};
use crate::mission::Mission;
use crate::physics::{
    start_case, BatteryCheck, Budget, LegEnergy, PhysicsError, Pricing, Profile, Start, Wind,
};
use crate::tour::clusters::Visit;
use crate::tour::energy::energy_matrix_of_legs;
use crate::tour::orders::{baseline, energy_order, plan_orders, SolvedOrder};
use crate::tour::sorties::{self, Method, SortieError, SortieOptions, SortieProblem};
use crate::tour::{
    cancel, held_karp, pairs, solver, CostMatrix, Direction, Geometry, Objective, PlanError, Proof,
};

pub use crate::physics::VehicleModel;
pub use explain::{Explanation, Saving};

/// Which orders a plan computes; the order it flies (the one its battery check prices) follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orders {
    /// The minimum-energy order and every distance baseline both ways (`emplan plan`); the
    /// energy order is flown.
    All,
    /// The minimum-energy order alone, flown.
    Energy,
    /// The minimum-distance baseline both ways; its cheaper direction (in energy) is flown.
    Distance,
    /// The order the mission file lists, flown as listed; nothing is solved.
    Listed,
}

/// What to plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    pub orders: Orders,
    pub solver: solver::Options,
    /// Also split the mission into sorties of least total energy, one battery each (needs the
    /// energy order: `All` or `Energy`, and settled pricing).
    pub sorties: bool,
    /// What a leg's energy counts, for the orders and their energies: to settled hover (the
    /// default) or to the paper's 4 m rule. The battery check always counts everything the
    /// battery pays (settled).
    pub pricing: Pricing,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            orders: Orders::All,
            solver: solver::Options::default(),
            sorties: false,
            pricing: Pricing::Settled,
        }
    }
}

/// One leg of an order as the model predicts it.
#[derive(Debug, Clone, PartialEq)]
pub struct Leg {
    /// Node ids (0 = origin).
    pub from: usize,
    pub to: usize,
    pub horizontal_m: f64,
    /// Signed vertical displacement (positive = climb).
    pub vertical_m: f64,
    /// 3D distance.
    pub distance_m: f64,
    /// Energy and time to the paper's 4 m rule (`energy_j`, `duration_s`) and from there to
    /// settled hover at the next point (`settle_energy_j`, `settle_duration_s`).
    pub predicted: LegEnergy,
    /// What [`Leg::energy_j`] counts.
    pub pricing: Pricing,
    /// Where the leg starts relative to PX4's trajectory, from the turn out of the leg before
    /// (`physics::start_case`; only the `px4` profile's price depends on it).
    pub start: Start,
    /// The points the leg passes through, without a hold, on its way round a fence zone, in
    /// the mission's local frame (empty: the leg flies straight). Its distances and its
    /// predicted energy are the whole chain's.
    pub via: Vec<crate::mission::Enu>,
    /// The fence zones a leg with `via` points goes round (0-based indices into the mission's
    /// fence), and what its straight line would have measured and cost (the cost None when
    /// the model cannot price it); None for a straight leg.
    pub detour: Option<DetourOf>,
    /// The block (an index into the mission's blocks) when the leg flies between two of its
    /// waypoints: a leg of the block's own lines, priced as the profile flies the block.
    pub block: Option<usize>,
}

/// What a leg routed round the fence goes round, and its straight line for comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct DetourOf {
    pub zones: Vec<usize>,
    pub straight_distance_m: f64,
    pub straight_energy_j: Option<f64>,
}

impl Leg {
    /// The leg's energy as its plan prices it (settled: everything the battery pays, start to
    /// settled hover; paper: to the 4 m rule).
    pub fn energy_j(&self) -> f64 {
        self.predicted.priced_energy_j(self.pricing)
    }

    /// The leg's duration as its plan prices it.
    pub fn duration_s(&self) -> f64 {
        self.predicted.priced_duration_s(self.pricing)
    }

    /// Everything the battery pays for the leg, start to settled hover (whatever the pricing).
    pub fn settled_energy_j(&self) -> f64 {
        self.predicted.total_energy_j()
    }
}

/// One visiting order, priced.
#[derive(Debug, Clone, PartialEq)]
pub struct Order {
    /// What chose it; `None` for the listed order (the mission file's own, not solved).
    pub objective: Option<Objective>,
    pub direction: Direction,
    /// Node ids in visiting order, origin excluded.
    pub nodes: Vec<usize>,
    /// origin -> nodes... -> origin.
    pub legs: Vec<Leg>,
    pub distance_m: f64,
    pub horizontal_m: f64,
    /// Total absolute vertical distance.
    pub vertical_m: f64,
    /// Sum of the legs' energies (as the plan prices them) and of the turns at the waypoints
    /// (`actions_j`).
    pub energy_j: f64,
    /// The turns in hover the waypoints' yaw actions ask for on arriving from the waypoint
    /// before in this order (0 without yaw actions).
    pub actions_j: f64,
    /// Sum of the legs' durations.
    pub duration_s: f64,
    /// What the solver proved (in J for the energy order, metres for a baseline); absent on
    /// reversed baselines and the listed order.
    pub proof: Option<Proof>,
    /// The mission's blocks in the order flown, each with the direction it is flown in (empty
    /// for a mission without blocks).
    pub blocks: Vec<FlownBlock>,
}

/// A block as an order flies it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FlownBlock {
    /// Index into the mission's blocks.
    pub block: usize,
    /// Flown last waypoint first.
    pub reversed: bool,
}

impl Order {
    /// The order as 0-based indices into the mission's waypoints.
    pub fn waypoints(&self) -> Vec<usize> {
        self.nodes.iter().map(|&n| n - 1).collect()
    }
}

/// One sortie of a split mission: origin -> its waypoints -> origin on a fresh battery.
#[derive(Debug, Clone, PartialEq)]
pub struct Sortie {
    /// Node ids in flying order, origin excluded.
    pub nodes: Vec<usize>,
    pub legs: Vec<Leg>,
    /// Its take-off, legs, hovering and landing against one battery.
    pub battery: BatteryCheck,
}

/// A mission split into sorties of least total energy.
#[derive(Debug, Clone, PartialEq)]
pub struct Sorties {
    pub method: Method,
    /// Whether the total is proven minimal (exact split).
    pub optimal: bool,
    /// Energy of all sorties together.
    pub total_j: f64,
    /// Ordered by their lowest waypoint.
    pub sorties: Vec<Sortie>,
}

/// A mission planned with a vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The mission's name.
    pub mission: String,
    pub profile: Profile,
    /// What the legs' energies count (the battery check always counts everything).
    pub pricing: Pricing,
    /// What was asked for.
    pub asked: Orders,
    /// `names[node]`: "origin", then the waypoints' names.
    pub names: Vec<String>,
    /// The orders computed: with `All`, the energy order, then each distance baseline forward
    /// and reverse; with `Energy` the energy order; with `Distance` the distance baseline
    /// forward and reverse; with `Listed` the listed order.
    pub orders: Vec<Order>,
    /// Index in `orders` of the order to fly.
    pub flown: usize,
    /// Take-off, landing, hover power and the battery.
    pub budget: Budget,
    /// Hold time at each waypoint (s), in file order: its hover and its actions' holds
    /// (`mission::Waypoint::hold_s`).
    pub hover_s: Vec<f64>,
    /// The turn in hover (s) at each waypoint (file order) its yaw actions ask for in the
    /// flown order (arriving from the waypoint before it).
    pub turn_s: Vec<f64>,
    /// The horizontal speed on the way to each node (0: home, then the waypoints in file
    /// order), None for the vehicle's own: the file's, kept in every order
    /// (`mission::actions`).
    pub speeds_m_s: Vec<Option<f64>>,
    /// The actions of the flown order, place by place (empty for a mission without actions).
    pub actions: Vec<ActionsAt>,
    /// The flown order against one battery.
    pub battery: BatteryCheck,
    /// The split into sorties, when asked for.
    pub sorties: Option<Sorties>,
    /// Where the energy order saves against the distance order (with `All`).
    pub explanation: Option<Explanation>,
    /// Energy of every leg as the plan prices it (J), node 0 = origin.
    pub energy: CostMatrix,
    /// The wind every price is in (calm: still air, the table's).
    pub wind: Wind,
    /// In wind, with the energy order asked for: the order still air would choose, priced in
    /// the wind, to set beside the wind-aware energy order.
    pub still_air: Option<StillAir>,
    /// The mission's origin (where the legs' via points are, geodetically).
    pub origin: crate::mission::Origin,
    /// How each fence zone is named ("exclusion polygon 1"), in the fence's order.
    pub zones: Vec<String>,
    /// How far every leg keeps from the fence's zones (m).
    pub fence_margin_m: f64,
    /// The autopilot's return from every waypoint of the flown order (a mission with a fence
    /// or rally points): where it goes, its price against the battery, the zones it crosses.
    pub returns: Option<returns::Returns>,
    /// What the plan could not do as asked, or did otherwise, in words (a block split across
    /// sorties, a refinement left out for a mission with blocks).
    pub notes: Vec<String>,
    /// Each block's ways as priced (empty without blocks).
    pub block_ways: blocks::BlockWays,
    /// The mission's blocks (`Order::blocks` and `Leg::block` index them).
    pub blocks: Vec<crate::mission::blocks::Block>,
}

/// One command at a place of the flown order, priced.
#[derive(Debug, Clone, PartialEq)]
pub struct PricedAction {
    /// Its MAV_CMD id.
    pub command: u16,
    /// What it does (`photo`, `speed 8 m/s`).
    pub what: String,
    /// The time the vehicle hovers for it: a hold, or a turn at the autopilot's yaw rate; 0
    /// where the autopilot does not wait (a photo, a gimbal move, a payload, a setting).
    pub hold_s: f64,
    pub energy_j: f64,
}

/// The actions at one place of the flown order (the start, then each waypoint flown), and the
/// commands emplan inserts after them to restore the file's settings for what comes next.
#[derive(Debug, Clone, PartialEq)]
pub struct ActionsAt {
    /// Node (0: the start, after the take-off).
    pub node: usize,
    pub actions: Vec<PricedAction>,
    /// (the setting restored, its MAV_CMD id, what it does).
    pub inserted: Vec<(&'static str, u16, String)>,
}

/// The still-air energy order of a plan made in wind.
#[derive(Debug, Clone, PartialEq)]
pub struct StillAir {
    /// The order minimum-energy in still air, its legs priced in the plan's wind.
    pub order: Order,
    /// Its price in still air (J, the plan's pricing).
    pub still_air_energy_j: f64,
}

impl Plan {
    /// What the wind-aware energy order saves against the still-air order flown in the same
    /// wind (J, and % of the still-air order's price in the wind); None in still air.
    pub fn wind_saving(&self) -> Option<(f64, f64)> {
        let still = self.still_air.as_ref()?;
        let aware = self.cheapest(Objective::Energy)?;
        let saving = still.order.energy_j - aware.energy_j;
        let pct = if still.order.energy_j > 0.0 {
            100.0 * saving / still.order.energy_j
        } else {
            0.0
        };
        Some((saving, pct))
    }
}

/// What one upload flies: the flown order, or one sortie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Flight<'a> {
    /// The sortie (1-based), if one was chosen.
    pub sortie: Option<usize>,
    /// Node ids in flying order, origin excluded.
    pub nodes: &'a [usize],
    pub legs: &'a [Leg],
    pub battery: &'a BatteryCheck,
}

impl Flight<'_> {
    /// The flight as 0-based indices into the mission's waypoints.
    pub fn waypoints(&self) -> Vec<usize> {
        self.nodes.iter().map(|&n| n - 1).collect()
    }

    /// Refuses a flight the battery cannot fly with its reserve.
    pub fn require_feasible(&self) -> Result<(), PlannerError> {
        let b = self.battery;
        if b.total_j > b.usable_j {
            return Err(PlannerError::OverBudget {
                predicted_j: b.total_j,
                usable_j: b.usable_j,
                reserve_pct: b.reserve_pct,
            });
        }
        Ok(())
    }
}

impl Plan {
    /// The order to fly.
    pub fn flown(&self) -> &Order {
        &self.orders[self.flown]
    }

    /// The first order computed for `objective`.
    pub fn order(&self, objective: Objective) -> Option<&Order> {
        self.orders.iter().find(|o| o.objective == Some(objective))
    }

    /// The order of `objective` with the least energy (the better direction of a baseline; the
    /// first one on a tie).
    pub fn cheapest(&self, objective: Objective) -> Option<&Order> {
        cheapest(&self.orders, objective)
    }

    /// Name of a node.
    pub fn name(&self, node: usize) -> &str {
        self.names.get(node).map_or("?", String::as_str)
    }

    /// Energy of hovering at waypoint `waypoint` (0-based).
    pub fn hover_j(&self, waypoint: usize) -> f64 {
        self.budget
            .hover_j(self.hover_s.get(waypoint).copied().unwrap_or(0.0))
    }

    /// What to upload: sortie `sortie` (1-based) of the split, or the flown order.
    pub fn flight(&self, sortie: Option<usize>) -> Result<Flight<'_>, PlannerError> {
        let Some(k) = sortie else {
            let order = self.flown();
            return Ok(Flight {
                sortie: None,
                nodes: &order.nodes,
                legs: &order.legs,
                battery: &self.battery,
            });
        };
        let count = self.sorties.as_ref().map_or(0, |s| s.sorties.len());
        let chosen = k
            .checked_sub(1)
            .and_then(|i| self.sorties.as_ref()?.sorties.get(i))
            .ok_or(PlannerError::NoSuchSortie { sortie: k, count })?;
        Ok(Flight {
            sortie: Some(k),
            nodes: &chosen.nodes,
            legs: &chosen.legs,
            battery: &chosen.battery,
        })
    }
}

/// The order an upload flies (`emplan upload --order`, the service's upload request).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FlownOrder {
    /// The minimum-energy order.
    #[default]
    Energy,
    /// The minimum-distance order, in its cheaper direction.
    Distance,
    /// The order the mission file lists.
    Listed,
}

/// What to fly of a mission: an order, or one sortie of the split (`upload`, `fly`, the
/// service). Planning computes only that order (no baselines for the energy order or a sortie,
/// no energy solve for the distance or the listed order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FlightChoice {
    pub order: FlownOrder,
    /// Sortie K (1-based) of the minimum-energy split into sorties, one battery each.
    pub sortie: Option<usize>,
    /// Go ahead when the model says the battery cannot fly it with its reserve.
    pub allow_infeasible: bool,
}

impl FlightChoice {
    /// The plan options that compute what this choice flies.
    pub fn options(&self, solver: solver::Options) -> PlanOptions {
        let orders = match (self.sortie, self.order) {
            (Some(_), _) | (None, FlownOrder::Energy) => Orders::Energy,
            (None, FlownOrder::Distance) => Orders::Distance,
            (None, FlownOrder::Listed) => Orders::Listed,
        };
        PlanOptions {
            orders,
            solver,
            sorties: self.sortie.is_some(),
            pricing: Pricing::Settled,
        }
    }

    /// Plans `mission` for this choice.
    pub fn plan(
        &self,
        mission: &Mission,
        model: &VehicleModel,
        solver: solver::Options,
    ) -> Result<Plan, PlannerError> {
        plan_mission(mission, model, &self.options(solver))
    }

    /// The flight chosen from `plan` (made by [`FlightChoice::plan`]), refused when the battery
    /// cannot fly it with its reserve unless `allow_infeasible`.
    pub fn flight<'a>(&self, plan: &'a Plan) -> Result<Flight<'a>, PlannerError> {
        let flight = plan.flight(self.sortie)?;
        if !self.allow_infeasible {
            flight.require_feasible()?;
        }
        Ok(flight)
    }
}

/// Everything planning can refuse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlannerError {
    // The cause is part of the message (not a `#[source]`), so that a chain of causes printed
    // one after the other does not repeat it.
    #[error("pricing the legs of mission {mission}: {cause}")]
    Pricing { mission: String, cause: PlanError },
    #[error("planning mission {mission}: {cause}")]
    Planning { mission: String, cause: PlanError },
    #[error("pricing the autopilot's return from {waypoint} to {to}: {message}")]
    Return {
        waypoint: String,
        to: String,
        message: String,
    },
    /// Take-off, landing or hover the model cannot price.
    #[error(transparent)]
    Budget(PhysicsError),
    #[error(
        "{place}: a speed of {speed_m_s} m/s is above the vehicle's planning.max_speed_m_s of \
         {max_m_s} m/s (the autopilot would clip it; lower the DO_CHANGE_SPEED)"
    )]
    TooFast {
        place: String,
        speed_m_s: f64,
        max_m_s: f64,
    },
    #[error(
        "waypoint {waypoint} cannot be flown even on a battery of its own: take-off, flying out, \
         hovering {hover_s:.0} s, flying back and landing need {:.1} kJ but one battery has {:.1} \
         kJ usable after its {reserve_pct}% reserve",
        .alone_j / 1000.0,
        .usable_j / 1000.0
    )]
    Unreachable {
        waypoint: String,
        hover_s: f64,
        alone_j: f64,
        usable_j: f64,
        reserve_pct: f64,
    },
    #[error("splitting mission {mission} into sorties: {cause}")]
    Sorties { mission: String, cause: SortieError },
    #[error("splitting mission {mission} into sorties needs its energy order")]
    SortiesNeedTheEnergyOrder { mission: String },
    #[error(
        "splitting mission {mission} into sorties needs settled pricing (a battery pays each \
         leg's settle; the paper's pricing leaves it out)"
    )]
    SortiesNeedSettledPricing { mission: String },
    #[error("sortie {sortie}: the mission splits into {count} sorties (1 to {count})")]
    NoSuchSortie { sortie: usize, count: usize },
    #[error(
        "{what}: {value} m {measure}, above the vehicle's limit planning.{limit} = {max} m (an \
         operating limit: --allow-infeasible does not override it)"
    )]
    OutsideLimit {
        /// The waypoint, the origin or the leg at fault.
        what: String,
        measure: &'static str,
        value: f64,
        limit: &'static str,
        max: f64,
    },
    #[error(
        "the model predicts {:.1} kJ for this mission but the battery has {:.1} kJ usable after \
         its {reserve_pct}% reserve",
        .predicted_j / 1000.0,
        .usable_j / 1000.0
    )]
    OverBudget {
        predicted_j: f64,
        usable_j: f64,
        reserve_pct: f64,
    },
    #[error(
        "leg {from} -> {to}: no way round {zone} keeping {margin_m} m from every fence zone \
         (is {from} or {to} boxed in?)"
    )]
    NoDetour {
        from: String,
        to: String,
        zone: String,
        margin_m: f64,
    },
    /// The thread's cancel token asked the plan to stop (`tour::cancel`).
    #[error("planning mission {mission} was stopped before it finished")]
    Cancelled { mission: String },
}

/// Refuses a mission whose origin or any waypoint is higher above home than the vehicle may fly.
fn within_height_limit(
    mission: &Mission,
    planning: &crate::physics::vehicle::Planning,
) -> Result<(), PlannerError> {
    let max = planning.max_height_above_home_m;
    let origin = mission.origin.height_above_home_m;
    let heights = std::iter::once(("origin".to_string(), origin)).chain(
        mission
            .waypoints
            .iter()
            .map(|w| (format!("waypoint {}", w.name), origin + w.position.z_up_m)),
    );
    let over: Vec<(String, f64)> = heights.filter(|(_, h)| *h > max || h.is_nan()).collect();
    let Some(highest) = over.iter().map(|(_, h)| *h).reduce(f64::max) else {
        return Ok(());
    };
    let mut what: Vec<String> = over.iter().take(5).map(|(w, _)| w.clone()).collect();
    if over.len() > 5 {
        what.push(format!("{} more", over.len() - 5));
    }
    Err(PlannerError::OutsideLimit {
        what: what.join(", "),
        measure: if over.len() > 1 {
            "above home at the highest"
        } else {
            "above home"
        },
        value: highest,
        limit: "max_height_above_home_m",
        max,
    })
}

/// Refuses a flight with a leg longer than the vehicle may fly in one go.
fn within_leg_limit(
    legs: &[Leg],
    names: &[String],
    planning: &crate::physics::vehicle::Planning,
) -> Result<(), PlannerError> {
    let max = planning.max_leg_m;
    match legs.iter().find(|l| l.distance_m > max) {
        Some(l) => Err(PlannerError::OutsideLimit {
            what: format!(
                "leg {} -> {}",
                names.get(l.from).map_or("?", String::as_str),
                names.get(l.to).map_or("?", String::as_str)
            ),
            measure: "long",
            value: (l.distance_m * 10.0).round() / 10.0,
            limit: "max_leg_m",
            max,
        }),
        None => Ok(()),
    }
}

/// The order of `objective` among `orders` with the least energy, the first on a tie.
fn cheapest(orders: &[Order], objective: Objective) -> Option<&Order> {
    orders
        .iter()
        .filter(|o| o.objective == Some(objective))
        .min_by(|a, b| a.energy_j.total_cmp(&b.energy_j))
}

/// Plans `mission` with `model` as `options` ask: prices every leg from the vehicle's energy
/// table, solves the orders asked for, checks the flown order against the battery, and splits
/// into sorties when asked.
pub fn plan_mission(
    mission: &Mission,
    model: &VehicleModel,
    options: &PlanOptions,
) -> Result<Plan, PlannerError> {
    let planned = plan_uncancelled(mission, model, options);
    // A phase asked to stop answers early (a solver its best tour so far): not a plan to keep.
    if cancel::requested() {
        return Err(PlannerError::Cancelled {
            mission: mission.name.clone(),
        });
    }
    let mut plan = planned?;
    plan.returns = returns::of(&plan, mission, model)?;
    Ok(plan)
}

/// [`plan_mission`], skipping what is left once the cancel token asks. In wind, with the energy
/// order asked for, the still-air energy order is planned on a thread of its own (with this
/// thread's cancel token) while the wind's legs are priced and ordered, and joined to be priced
/// in the wind.
fn plan_uncancelled(
    mission: &Mission,
    model: &VehicleModel,
    options: &PlanOptions,
) -> Result<Plan, PlannerError> {
    let wants_still_air =
        !model.wind.is_calm() && matches!(options.orders, Orders::All | Orders::Energy);
    if !wants_still_air {
        return plan_core(mission, model, options, None);
    }
    let calm = model.clone().with_wind(Wind::CALM);
    let calm_options = PlanOptions {
        orders: Orders::Energy,
        sorties: false,
        ..options.clone()
    };
    let token = cancel::current();
    std::thread::scope(|scope| {
        // Started once the wind's legs are priced (both cores then free of them), so that it
        // runs beside the single-threaded solves.
        let start = || {
            scope.spawn(|| {
                let plan = || plan_core(mission, &calm, &calm_options, None);
                match &token {
                    Some(token) => cancel::within(token, plan),
                    None => plan(),
                }
            })
        };
        plan_core(mission, model, options, Some(&start))
    })
}

/// A plan whose still-air energy order comes from another thread.
type StillAirPlan<'scope> = std::thread::ScopedJoinHandle<'scope, Result<Plan, PlannerError>>;

/// The plan of [`plan_uncancelled`]; `start_still_air`, in wind, starts the still-air plan.
fn plan_core<'scope>(
    mission: &Mission,
    model: &VehicleModel,
    options: &PlanOptions,
    start_still_air: Option<&dyn Fn() -> StillAirPlan<'scope>>,
) -> Result<Plan, PlannerError> {
    let stopped = || PlannerError::Cancelled {
        mission: mission.name.clone(),
    };
    within_height_limit(mission, &model.vehicle.planning)?;
    if options.sorties && options.pricing != Pricing::Settled {
        return Err(PlannerError::SortiesNeedSettledPricing {
            mission: mission.name.clone(),
        });
    }
    let straight = Geometry::from_mission(mission);
    let names: Vec<String> = std::iter::once("origin".to_string())
        .chain(mission.waypoints.iter().map(|w| w.name.clone()))
        .collect();
    let budget = model
        .budget(mission.origin.height_above_home_m)
        .map_err(PlannerError::Budget)?;
    // The speed on the way to each node (node 0: home), the file's in every order.
    let (to_waypoint, home_speed) = mission.speeds_m_s();
    let speeds: Vec<Option<f64>> = std::iter::once(home_speed).chain(to_waypoint).collect();
    for (node, speed) in speeds.iter().enumerate() {
        if let Some(v) = *speed {
            let max_m_s = model.vehicle.planning.max_speed_m_s;
            if v > max_m_s {
                return Err(PlannerError::TooFast {
                    place: if node == 0 {
                        "the way home".into()
                    } else {
                        format!("the way to waypoint {}", names[node])
                    },
                    speed_m_s: v,
                    max_m_s,
                });
            }
        }
    }
    let mut at_speeds: Vec<(Option<f64>, VehicleModel)> = Vec::new();
    for speed in &speeds {
        if !at_speeds.iter().any(|(v, _)| v == speed) {
            at_speeds.push((*speed, model.at_speed(*speed)));
        }
    }
    // The model a leg into `to` is flown with: at the speed in force on the way there.
    let model_to = |to: usize| -> &VehicleModel {
        at_speeds
            .iter()
            .find(|(v, _)| *v == speeds[to])
            .map_or(model, |(_, m)| m)
    };
    let zone_names: Vec<String> = mission
        .fence
        .zones
        .iter()
        .enumerate()
        .map(|(k, z)| z.describe(k + 1))
        .collect();
    // Every pair whose straight line breaks the fence, routed round it the cheapest way in
    // energy, each path priced as the chain of legs it is.
    let margin_m = detour::FENCE_MARGIN_M;
    let detours = detour::route(
        mission,
        straight.points(),
        margin_m,
        |from, to, via| {
            let points = straight.points();
            detour::price_chain(model_to(to), points[from], via, points[to], Start::Behind)
                .map_err(|e| (from, to, e))
        },
        |leg| leg.priced_energy_j(options.pricing),
    )
    .map_err(|e| match e {
        detour::RouteError::NoRoute(r) => PlannerError::NoDetour {
            from: names[r.from].clone(),
            to: names[r.to].clone(),
            zone: zone_names.get(r.zone).cloned().unwrap_or_default(),
            margin_m,
        },
        detour::RouteError::Price((from, to, e)) => PlannerError::Pricing {
            mission: mission.name.clone(),
            cause: PlanError::LegEnergy {
                from: names[from].clone(),
                to: names[to].clone(),
                xf_m: straight.horizontal_m(from, to),
                zf_m: straight.vertical_m(from, to),
                reason: format!("round the fence: {e}"),
            },
        },
    })?;
    let geometry = straight.clone().with_via(detours.via());
    let yaw_rate_deg_s = yaw_rate_deg_s(model.profile);
    let turns = mission.waypoints.iter().any(|w| {
        w.actions
            .iter()
            .any(|c| matches!(c.action(), Action::Yaw { .. }))
    });
    // The turn in hover at `to` arriving from `from` (0 at home or without yaw actions).
    let turn_s = |from: usize, to: usize| -> f64 {
        if !turns || to == 0 {
            return 0.0;
        }
        // The heading it arrives on: from its last via point round a zone, if any.
        let (_, (dx, dy)) = geometry.departure_and_arrival(from, to);
        yaw_s(
            &mission.waypoints[to - 1].actions,
            crate::mission::wind::heading_deg(dx, dy),
            yaw_rate_deg_s,
        )
    };
    let turn_j = |from: usize, to: usize| budget.hover_j(turn_s(from, to));
    let pricing = |cause| PlannerError::Pricing {
        mission: mission.name.clone(),
        cause,
    };
    let planning = |cause| PlannerError::Planning {
        mission: mission.name.clone(),
        cause,
    };
    // The turn into the leg: from the way the leg before arrives (from its last via point)
    // to the way this one leaves (towards its first).
    let start_of = |previous: Option<usize>, from: usize, to: usize| -> Start {
        start_case(
            previous.map(|p| geometry.departure_and_arrival(p, from).1),
            geometry.departure_and_arrival(from, to).0,
        )
    };
    let solver = &options.solver;
    let mut notes: Vec<String> = Vec::new();
    // Each block's ways, priced once: its lines as the profile flies the block, each at the
    // speed the file flies it at.
    let block_ways = if mission.has_blocks() {
        use rayon::prelude::*;
        let line_speed = |a: usize, b: usize| speeds[a.max(b)];
        let model_at = |v: Option<f64>| -> &VehicleModel {
            at_speeds
                .iter()
                .find(|(s, _)| *s == v)
                .map_or(model, |(_, m)| m)
        };
        let jobs: Vec<(usize, bool)> = mission
            .blocks
            .iter()
            .enumerate()
            .flat_map(|(b, block)| {
                std::iter::once((b, false)).chain(block.reversible.then_some((b, true)))
            })
            .collect();
        let priced: Vec<Result<blocks::PricedWay, blocks::PriceFailure>> = jobs
            .par_iter()
            .map(|&(b, reversed)| {
                blocks::price_way(
                    mission,
                    b,
                    reversed,
                    straight.points(),
                    &line_speed,
                    &model_at,
                    &turn_j,
                    options.pricing,
                )
            })
            .collect();
        let mut ways = blocks::BlockWays {
            ways: vec![[None, None]; mission.blocks.len()],
        };
        for (&(b, reversed), way) in jobs.iter().zip(priced) {
            let way = way.map_err(|(from, to, e)| {
                pricing(PlanError::LegEnergy {
                    from: names[from].clone(),
                    to: names[to].clone(),
                    xf_m: straight.horizontal_m(from, to),
                    zf_m: straight.vertical_m(from, to),
                    reason: format!("flying block {}: {e}", mission.blocks[b].name),
                })
            })?;
            ways.ways[b][usize::from(reversed)] = Some(way);
        }
        ways
    } else {
        blocks::BlockWays::default()
    };
    // The distance baselines need only the geometry. Of a mission Held-Karp solves exactly
    // (the min-vertical baseline's lexicographic Held-Karp is the slowest solve of a
    // 20-waypoint plan) they run on a thread of their own from the start, beside the energy
    // pricing and solve, each solve within the time limit as before; a larger mission's
    // solves share the time limit one after the other on this thread, their progress shown.
    let parallel_baselines = options.orders == Orders::All
        && geometry.len() <= held_karp::MAX_NODES + 1
        && !mission.has_blocks();
    let token = cancel::current();
    let (energy, still_air_plan, solved, pair_skipped) = std::thread::scope(|scope| {
        let baselines = parallel_baselines.then(|| {
            scope.spawn(|| {
                let solve = || plan_orders(&geometry, None, solver);
                match &token {
                    Some(token) => cancel::within(token, solve),
                    None => solve(),
                }
            })
        });
        // In still air a leg is the table's; in wind, or at a speed a DO_CHANGE_SPEED set, it
        // is simulated on its heading; a turn at its end is priced with it.
        let energy = energy_matrix_of_legs(&geometry, &names, |from, to, x, z, heading| {
            if let Some(d) = detours.get(from, to) {
                return Ok(d.predicted.priced_energy_j(options.pricing) + turn_j(from, to));
            }
            model_to(to)
                .leg_on_heading(x, z, Start::Behind, heading)
                .map(|leg| leg.priced_energy_j(options.pricing) + turn_j(from, to))
        })
        .map_err(pricing)?;
        // A leg's price after a turn of less than 90 degrees (the px4 profile's vehicle starts
        // it ahead of PX4's trajectory); the same matrix for the profiles that do not depend on
        // it.
        let ahead = if model.table.starts.contains(&Start::Ahead) {
            Some(
                energy_matrix_of_legs(&geometry, &names, |from, to, x, z, heading| {
                    if let Some(d) = detours.get(from, to) {
                        let points = geometry.points();
                        return detour::price_chain(
                            model_to(to),
                            points[from],
                            &d.via,
                            points[to],
                            Start::Ahead,
                        )
                        .map(|leg| leg.priced_energy_j(options.pricing) + turn_j(from, to));
                    }
                    model_to(to)
                        .leg_on_heading(x, z, Start::Ahead, heading)
                        .map(|leg| leg.priced_energy_j(options.pricing) + turn_j(from, to))
                })
                .map_err(pricing)?,
            )
        } else {
            None
        };
        let still_air_plan = start_still_air.map(|start| start());
        let pair_aware = |mut order: SolvedOrder| -> Result<SolvedOrder, PlannerError> {
            match (&ahead, order.objective) {
                (Some(ahead), Objective::Energy) => {
                    order = pair_energy_order(&energy, ahead, &start_of, order, &geometry, solver)
                        .map_err(planning)?;
                    Ok(order)
                }
                _ => Ok(order),
            }
        };
        let solved: Vec<SolvedOrder> = if mission.has_blocks() {
            // Points and blocks: each block a cluster of its ways (tour::clusters).
            let stop_orders = |objective, energy| {
                blocks::stop_orders(mission, &geometry, &straight, energy, objective, solver)
                    .map_err(planning)
            };
            let energy_order = || stop_orders(Objective::Energy, Some((&energy, &block_ways)));
            match options.orders {
                Orders::All => {
                    let mut all = energy_order()?;
                    for objective in [
                        Objective::Distance,
                        Objective::Horizontal,
                        Objective::Vertical,
                    ] {
                        all.extend(stop_orders(objective, None)?);
                    }
                    all
                }
                Orders::Energy => energy_order()?,
                Orders::Distance => stop_orders(Objective::Distance, None)?,
                Orders::Listed => Vec::new(),
            }
        } else {
            match (options.orders, baselines) {
                (Orders::All, Some(baselines)) => {
                    let energy_first =
                        energy_order(&geometry, &energy, solver).map_err(planning)?;
                    let rest = baselines
                        .join()
                        .map_err(|_| {
                            planning(PlanError::Infeasible(
                                "the distance baselines stopped unexpectedly".into(),
                            ))
                        })?
                        .map_err(planning)?;
                    std::iter::once(energy_first)
                        .chain(rest)
                        .map(pair_aware)
                        .collect::<Result<_, _>>()?
                }
                (Orders::All, None) => plan_orders(&geometry, Some(&energy), solver)
                    .map_err(planning)?
                    .into_iter()
                    .map(pair_aware)
                    .collect::<Result<_, _>>()?,
                (Orders::Energy, _) => vec![pair_aware(
                    energy_order(&geometry, &energy, solver).map_err(planning)?,
                )?],
                (Orders::Distance, _) => baseline(&geometry, Objective::Distance, solver)
                    .map_err(planning)?
                    .to_vec(),
                (Orders::Listed, _) => Vec::new(),
            }
        };
        let pair_skipped = ahead.is_some()
            && mission.has_blocks()
            && matches!(options.orders, Orders::All | Orders::Energy);
        Ok::<_, PlannerError>((energy, still_air_plan, solved, pair_skipped))
    })?;
    if pair_skipped {
        notes.push(
            "the px4 profile's refinement of the energy order by the turn between legs is left \
             out for a mission with blocks (each leg priced behind PX4's trajectory in the solve)"
                .into(),
        );
    }
    if cancel::requested() {
        return Err(stopped());
    }
    let leg = |previous: Option<usize>, from: usize, to: usize| -> Result<Leg, PlannerError> {
        // A line of a block: priced as the profile flies the whole block, straight.
        if let Some((b, inner)) = block_ways.inner(mission, from, to) {
            return Ok(Leg {
                from,
                to,
                horizontal_m: straight.horizontal_m(from, to),
                vertical_m: straight.vertical_m(from, to),
                distance_m: straight.distance_m(from, to),
                predicted: inner.predicted,
                pricing: options.pricing,
                start: inner.start,
                via: Vec::new(),
                detour: None,
                block: Some(b),
            });
        }
        let (horizontal_m, vertical_m) = (
            geometry.horizontal_m(from, to),
            geometry.vertical_m(from, to),
        );
        let start = start_of(previous, from, to);
        let detoured = detours.get(from, to);
        let priced = match detoured {
            Some(d) if start == Start::Behind => Ok(d.predicted),
            Some(d) => {
                let points = geometry.points();
                detour::price_chain(model_to(to), points[from], &d.via, points[to], start)
            }
            None => model_to(to).leg_on_heading(
                horizontal_m,
                vertical_m,
                start,
                geometry.heading_deg(from, to),
            ),
        };
        let predicted = priced.map_err(|e| {
            pricing(PlanError::LegEnergy {
                from: names[from].clone(),
                to: names[to].clone(),
                xf_m: horizontal_m,
                zf_m: vertical_m,
                reason: e.to_string(),
            })
        })?;
        Ok(Leg {
            from,
            to,
            horizontal_m,
            vertical_m,
            distance_m: geometry.distance_m(from, to),
            predicted,
            pricing: options.pricing,
            start,
            via: detoured.map(|d| d.via.clone()).unwrap_or_default(),
            block: None,
            detour: detoured.map(|d| DetourOf {
                zones: d.zones.clone(),
                straight_distance_m: straight.distance_m(from, to),
                straight_energy_j: model_to(to)
                    .leg_on_heading(
                        straight.horizontal_m(from, to),
                        vertical_m,
                        start,
                        straight.heading_deg(from, to),
                    )
                    .ok()
                    .map(|l| l.priced_energy_j(options.pricing)),
            }),
        })
    };
    let legs = |nodes: &[usize]| -> Result<Vec<Leg>, PlannerError> {
        let stops: Vec<usize> = std::iter::once(0)
            .chain(nodes.iter().copied())
            .chain(std::iter::once(0))
            .collect();
        stops
            .windows(2)
            .enumerate()
            .map(|(k, w)| leg(k.checked_sub(1).map(|p| stops[p]), w[0], w[1]))
            .collect()
    };
    let turns_j = |legs: &[Leg]| -> f64 { legs.iter().map(|l| turn_j(l.from, l.to)).sum() };
    let priced = |objective, direction, nodes: Vec<usize>, proof| -> Result<Order, PlannerError> {
        let legs = legs(&nodes)?;
        let actions_j = turns_j(&legs);
        let flown_blocks = blocks::flown_blocks(mission, &nodes);
        Ok(Order {
            objective,
            direction,
            distance_m: legs.iter().map(|l| l.distance_m).sum(),
            horizontal_m: legs.iter().map(|l| l.horizontal_m).sum(),
            vertical_m: legs.iter().map(|l| l.vertical_m.abs()).sum(),
            energy_j: legs.iter().map(Leg::energy_j).sum::<f64>() + actions_j,
            actions_j,
            duration_s: legs.iter().map(Leg::duration_s).sum(),
            nodes,
            legs,
            proof,
            blocks: flown_blocks,
        })
    };
    let orders: Vec<Order> = if options.orders == Orders::Listed {
        vec![priced(
            None,
            Direction::Forward,
            (1..=mission.waypoints.len()).collect(),
            None,
        )?]
    } else {
        // In wind each leg is a simulation: the orders are priced in parallel.
        use rayon::prelude::*;
        solved
            .into_par_iter()
            .map(|o| priced(Some(o.objective), o.direction, o.nodes, o.proof))
            .collect::<Result<Vec<_>, _>>()?
    };
    // With blocks, the file's own order is a baseline too (every block forward: as
    // QGroundControl would fly it).
    let mut orders = orders;
    if options.orders == Orders::All && mission.has_blocks() {
        orders.push(priced(
            None,
            Direction::Forward,
            (1..=mission.waypoints.len()).collect(),
            None,
        )?);
    }
    // With blocks the px4 profile's solve prices every leg behind PX4's trajectory, which the
    // order as flown is not (a turn of less than 90 degrees starts the next leg ahead); the
    // solved order flown backwards, every block flipped, is priced too and the cheaper flown.
    if pair_skipped && mission.blocks.iter().all(|b| b.reversible) {
        if let Some(k) = orders
            .iter()
            .position(|o| o.objective == Some(Objective::Energy))
        {
            let back: Vec<usize> = orders[k].nodes.iter().rev().copied().collect();
            let mut other = priced(
                Some(Objective::Energy),
                Direction::Forward,
                back,
                orders[k].proof.clone(),
            )?;
            if other.energy_j < orders[k].energy_j {
                notes.push(format!(
                    "the solved energy order flown backwards costs {:.2} kJ less with the turns \
                     between legs priced: it is flown so (its proof is the solve's, every leg \
                     priced behind)",
                    (orders[k].energy_j - other.energy_j) / 1000.0
                ));
                if let Some(proof) = other.proof.as_mut() {
                    proof.optimal = false;
                }
                orders[k] = other;
            }
        }
    }
    let flown = match options.orders {
        Orders::Distance => cheapest(&orders, Objective::Distance)
            .and_then(|c| orders.iter().position(|o| std::ptr::eq(o, c)))
            .unwrap_or(0),
        Orders::All | Orders::Energy | Orders::Listed => 0,
    };

    if let Some(order) = orders.get(flown) {
        within_leg_limit(&order.legs, &names, &model.vehicle.planning)?;
    }

    // In wind: the order still air would choose, priced in this wind.
    let still_air = match still_air_plan {
        Some(handle) => {
            let calm_plan = handle.join().map_err(|_| {
                planning(PlanError::Infeasible(
                    "the still-air plan stopped unexpectedly".into(),
                ))
            })??;
            let calm_order = calm_plan.orders.into_iter().next().ok_or_else(|| {
                planning(PlanError::Infeasible("no still-air energy order".into()))
            })?;
            Some(StillAir {
                still_air_energy_j: calm_order.energy_j,
                order: priced(
                    Some(Objective::Energy),
                    calm_order.direction,
                    calm_order.nodes,
                    calm_order.proof,
                )?,
            })
        }
        None => None,
    };

    let hover_s: Vec<f64> = mission.waypoints.iter().map(|w| w.hold_s()).collect();
    // The battery pays everything, whatever the pricing of the orders.
    let legs_j = orders
        .get(flown)
        .map_or(0.0, |o| o.legs.iter().map(Leg::settled_energy_j).sum());
    let mut turn_at = vec![0.0; mission.waypoints.len()];
    if let Some(order) = orders.get(flown) {
        for leg in &order.legs {
            if leg.to > 0 {
                turn_at[leg.to - 1] = turn_s(leg.from, leg.to);
            }
        }
    }
    let battery = budget.check(
        legs_j,
        budget.hover_j(hover_s.iter().sum::<f64>() + turn_at.iter().sum::<f64>()),
    );
    let actions = match orders.get(flown) {
        Some(order) if mission.has_actions() => {
            let flown_waypoints = order.waypoints();
            let inserted = mission.restoring(&flown_waypoints, Some(model.cruise_speed_m_s()));
            let places = std::iter::once(0).chain(order.nodes.iter().copied());
            places
                .zip(inserted)
                .map(|(node, inserted)| {
                    let commands = match node {
                        0 => &mission.start_actions,
                        n => &mission.waypoints[n - 1].actions,
                    };
                    let turn = if node == 0 { 0.0 } else { turn_at[node - 1] };
                    let yaws = commands
                        .iter()
                        .filter(|c| matches!(c.action(), Action::Yaw { .. }))
                        .count()
                        .max(1) as f64;
                    ActionsAt {
                        node,
                        actions: commands
                            .iter()
                            .map(|c| {
                                let hold_s = match c.action() {
                                    Action::Hold { duration_s } => duration_s,
                                    // The arrival's turn, shared among its yaws.
                                    Action::Yaw { .. } => turn / yaws,
                                    _ => 0.0,
                                };
                                PricedAction {
                                    command: c.command,
                                    what: c.describe(),
                                    hold_s,
                                    energy_j: budget.hover_j(hold_s),
                                }
                            })
                            .collect(),
                        inserted: inserted
                            .iter()
                            .map(|(setting, c)| (setting.name(), c.command, c.describe()))
                            .collect(),
                    }
                })
                .collect()
        }
        _ => Vec::new(),
    };

    let sorties = if options.sorties {
        if cancel::requested() {
            return Err(stopped());
        }
        let energy_order = cheapest(&orders, Objective::Energy).ok_or_else(|| {
            PlannerError::SortiesNeedTheEnergyOrder {
                mission: mission.name.clone(),
            }
        })?;
        let hover_j: Vec<f64> = hover_s.iter().map(|&s| budget.hover_j(s)).collect();
        let split = if mission.has_blocks() {
            // The split works on the stops, each block whole in the way the energy order flies
            // it; a block one battery cannot fly is split into its waypoints, and said so.
            let mut broken: Vec<usize> = Vec::new();
            loop {
                let set = blocks::StopSet::new(mission, &broken, |b, reversed| {
                    block_ways
                        .get(b, reversed)
                        .map_or(f64::INFINITY, |w| w.inner_j)
                });
                let visits = set.visits(mission, &energy_order.nodes);
                let mut way = vec![0; set.stops.len()];
                for v in &visits {
                    way[v.stop] = v.way;
                }
                let contracted = blocks::contract(&energy, &set, &way, &hover_j);
                let problem = SortieProblem {
                    energy: &contracted.energy,
                    hover_j: &contracted.hover_j,
                    fixed_j: budget.fixed_j(),
                    budget_j: budget.usable_j,
                };
                let split = sorties::split(
                    &problem,
                    &SortieOptions {
                        giant_tour: Some(visits.iter().map(|v| v.stop + 1).collect()),
                        ..SortieOptions::default()
                    },
                );
                let of_stops = |order: &[usize]| -> Vec<usize> {
                    let visits: Vec<Visit> = order
                        .iter()
                        .map(|&k| Visit {
                            stop: k - 1,
                            way: way[k - 1],
                        })
                        .collect();
                    set.nodes(mission, &visits)
                };
                match split {
                    Err(SortieError::Unreachable { node, .. })
                        if set.block.get(node - 1).is_some_and(Option::is_some) =>
                    {
                        let b = set.block[node - 1].unwrap_or_default();
                        notes.push(format!(
                            "block {} cannot be flown whole on one battery: its waypoints are \
                             split among the sorties as points",
                            mission.blocks[b].name
                        ));
                        broken.push(b);
                    }
                    Err(SortieError::Unreachable {
                        node,
                        alone_j,
                        budget_j,
                    }) => {
                        break Err(SortieError::Unreachable {
                            node: of_stops(&[node]).first().copied().unwrap_or(node),
                            alone_j,
                            budget_j,
                        })
                    }
                    Err(e) => break Err(e),
                    Ok(mut split) => {
                        for s in &mut split.sorties {
                            s.order = of_stops(&s.order);
                        }
                        break Ok(split);
                    }
                }
            }
        } else {
            let problem = SortieProblem {
                energy: &energy,
                hover_j: &hover_j,
                fixed_j: budget.fixed_j(),
                budget_j: budget.usable_j,
            };
            sorties::split(
                &problem,
                &SortieOptions {
                    giant_tour: Some(energy_order.nodes.clone()),
                    ..SortieOptions::default()
                },
            )
        }
        .map_err(|err| match err {
            SortieError::Unreachable { node, alone_j, .. } => {
                let waypoint = node.checked_sub(1).and_then(|k| mission.waypoints.get(k));
                PlannerError::Unreachable {
                    waypoint: waypoint.map_or(format!("node {node}"), |w| w.name.clone()),
                    hover_s: waypoint.map_or(0.0, |w| w.hold_s()),
                    alone_j,
                    usable_j: budget.usable_j,
                    reserve_pct: budget.reserve_pct,
                }
            }
            cause => PlannerError::Sorties {
                mission: mission.name.clone(),
                cause,
            },
        })?;
        let sorties: Vec<Sortie> = split
            .sorties
            .into_iter()
            .map(|s| {
                let legs = legs(&s.order)?;
                within_leg_limit(&legs, &names, &model.vehicle.planning)?;
                // The split chose on pair-independent costs; its battery check pays the legs
                // as flown, each after the one before.
                let legs_j = legs.iter().map(Leg::settled_energy_j).sum();
                let hover_j = s.hover_j + turns_j(&legs);
                Ok(Sortie {
                    legs,
                    battery: budget.check(legs_j, hover_j),
                    nodes: s.order,
                })
            })
            .collect::<Result<_, PlannerError>>()?;
        // Each sortie's legs priced after the one before (what its battery pays).
        let total_j = sorties.iter().map(|s: &Sortie| s.battery.total_j).sum();
        Some(Sorties {
            method: split.method,
            optimal: split.optimal,
            total_j,
            sorties,
        })
    } else {
        None
    };
    let explanation = match (
        cheapest(&orders, Objective::Energy),
        cheapest(&orders, Objective::Distance),
    ) {
        (Some(energy), Some(distance)) => Some(Explanation::of(energy, distance)),
        _ => None,
    };
    // Which end each block of the energy order is entered at, and what the other end costs.
    let explanation = explanation.map(|mut e| {
        if let Some(order) = cheapest(&orders, Objective::Energy) {
            let set = blocks::StopSet::new(mission, &[], |b, reversed| {
                block_ways
                    .get(b, reversed)
                    .map_or(f64::INFINITY, |w| w.inner_j)
            });
            let visits = set.visits(mission, &order.nodes);
            e.blocks = order
                .blocks
                .iter()
                .map(|f| explain::BlockEntry {
                    block: f.block,
                    reversed: f.reversed,
                    other_end_j: blocks::other_end_j(&energy, &set, &visits, f.block),
                })
                .collect();
        }
        e
    });
    Ok(Plan {
        mission: mission.name.clone(),
        profile: model.profile,
        pricing: options.pricing,
        asked: options.orders,
        names,
        orders,
        flown,
        budget,
        hover_s,
        turn_s: turn_at,
        speeds_m_s: speeds,
        actions,
        battery,
        sorties,
        explanation,
        energy,
        wind: model.wind,
        still_air,
        origin: mission.origin,
        zones: zone_names,
        fence_margin_m: margin_m,
        returns: None,
        notes,
        block_ways,
        blocks: mission.blocks.clone(),
    })
}

/// CONDITION_YAW's turn rate when it gives none (param2 0): ArduCopter's AUTO_YAW_SLEW_RATE
/// (ArduCopter/config.h, 60 deg/s).
const ARDUPILOT_YAW_RATE_DEG_S: f64 = 60.0;
/// How fast PX4 turns to a waypoint's yaw (the form PX4 flies CONDITION_YAW in,
/// `link::items::translate`): MPC_YAWRAUTO_MAX, 45 deg/s in PX4's parameter reference.
const PX4_YAW_RATE_DEG_S: f64 = 45.0;

/// The yaw rate a profile's autopilot turns at when an action gives none.
fn yaw_rate_deg_s(profile: Profile) -> f64 {
    match profile {
        Profile::Ardupilot => ARDUPILOT_YAW_RATE_DEG_S,
        _ => PX4_YAW_RATE_DEG_S,
    }
}

/// The energy order on the pair costs (a `px4` leg priced `behind` or `ahead` by the turn out
/// of the leg before, `start_of`), from the order `seed` chosen on the pair-independent
/// `behind` costs: exact for small missions, else local search with the proven bound of the
/// tour problem on each arc's cheapest cost ([`pairs`]).
fn pair_energy_order(
    behind: &CostMatrix,
    ahead: &CostMatrix,
    start_of: &impl Fn(Option<usize>, usize, usize) -> Start,
    seed: SolvedOrder,
    geometry: &Geometry,
    options: &solver::Options,
) -> Result<SolvedOrder, PlanError> {
    let started = std::time::Instant::now();
    let n = behind.len();
    let cost = |previous: Option<usize>, from: usize, to: usize| match start_of(previous, from, to)
    {
        Start::Behind => behind.cost(from, to),
        Start::Ahead => ahead.cost(from, to),
    };
    let bound = if n.saturating_sub(1) <= pairs::EXACT_MAX_WAYPOINTS {
        0.0
    } else {
        let minima = pairs::arc_minima(n, &cost);
        energy_order(geometry, &minima, options)?
            .proof
            .map_or(0.0, |p| p.lower_bound)
    };
    let solved = pairs::solve(n, &cost, seed.nodes.clone(), bound)?;
    let seed_proof = seed.proof.clone();
    let lower_bound = solved.lower_bound;
    Ok(SolvedOrder {
        nodes: solved.order,
        proof: Some(Proof {
            solver: seed_proof
                .as_ref()
                .map_or(solver::Solver::Auto, |p| p.solver),
            optimal: solved.optimal,
            lower_bound,
            gap_pct: if solved.cost > 0.0 {
                100.0 * (solved.cost - lower_bound).max(0.0) / solved.cost
            } else {
                0.0
            },
            seconds: seed_proof.map_or(0.0, |p| p.seconds) + started.elapsed().as_secs_f64(),
        }),
        ..seed
    })
}

#[cfg(test)]
mod tests;
