//! Vehicle parameters (`models/<vehicle>/vehicle.toml`): every key carries its unit, every value
//! its source in a comment. Loading validates ranges and names the offending key.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{PhysicsError, Profile};
use crate::mission::line_of;

/// Mission-planning settings (not physics: they do not affect the energy tables).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Planning {
    pub default_profile: Profile,
    pub usable_energy_wh: f64,
    pub reserve_pct: f64,
    /// Operating limits: a mission outside them is refused (`--allow-infeasible` overrides only
    /// the battery reserve, never these). Defaults for vehicle files written before they existed.
    #[serde(default = "default_max_height_above_home_m")]
    pub max_height_above_home_m: f64,
    #[serde(default = "default_max_leg_m")]
    pub max_leg_m: f64,
    #[serde(default = "default_max_speed_m_s")]
    pub max_speed_m_s: f64,
}

fn default_max_height_above_home_m() -> f64 {
    120.0
}

fn default_max_leg_m() -> f64 {
    1000.0
}

fn default_max_speed_m_s() -> f64 {
    16.0
}

/// Rigid body and environment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Body {
    pub mass_kg: f64,
    pub gravity_m_s2: f64,
    pub air_density_kg_m3: f64,
    pub drag_coefficient_n_s2_m2: f64,
    /// Vertical body drag C_BDz: F_z gains C_BDz Z'|Z'| (docs/energy-model.md; the paper
    /// neglects it). 0 for files written before it.
    #[serde(default)]
    pub vertical_drag_coefficient_n_s2_m2: f64,
    pub avionics_power_w: f64,
    pub max_tilt_deg: f64,
}

/// Rotor and propeller geometry and aerodynamics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotorParams {
    pub count: u32,
    pub blades: u32,
    pub radius_m: f64,
    pub root_cutout_m: f64,
    pub tip_loss_factor: f64,
    pub chord_m: f64,
    pub geometric_pitch_m: f64,
    pub collective_offset_deg: f64,
    pub lift_slope_per_rad: f64,
    pub drag_coefficient: f64,
    /// Induced power factor kappa: the blade-element inflow is kappa times momentum theory's
    /// uniform induced velocity (non-uniform inflow; Leishman, "Principles of Helicopter
    /// Aerodynamics", 2nd ed., section 3.3: about 1.15). 1 (ideal) for files written before it.
    #[serde(default = "default_induced_power_factor")]
    pub induced_power_factor: f64,
    /// The share of a descent's rate that reaches the rotors' inflow: 1 in momentum theory (the
    /// paper's model, every descent crediting its fall through the disk); below 1 a rotor that
    /// recovers less of it (docs/energy-model.md "Descent"). 1 for files written before it.
    /// Left out of the serialised parameters (and so of the tables' vehicle hash) at 1.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub descent_inflow_factor: f64,
    /// The share of the vehicle's airspeed (in the rotor's frame, in-plane and through the
    /// disk, after the descent's share) that reaches the rotors' aerodynamics: 1 in momentum
    /// and blade-element theory (translational lift, the work of climbing, parasite power);
    /// 0 a rotor whose power follows its thrust alone, as ArduPilot's SITL motors
    /// (libraries/SITL/SIM_Motor.cpp: power = factor x thrust). docs/energy-model.md
    /// "Airflow". 1 for files written before it; left out of the serialised parameters at 1.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub airflow_factor: f64,
}

/// The default of a share that is whole in the paper's model (descent inflow, airflow).
fn one() -> f64 {
    1.0
}

fn is_one(x: &f64) -> bool {
    *x == 1.0
}

fn default_induced_power_factor() -> f64 {
    1.0
}

/// Brushless motor and ESC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorParams {
    pub kv_rpm_per_v: f64,
    pub resistance_ohm: f64,
    pub no_load_current_a: f64,
    pub esc_efficiency: f64,
}

/// Lumped battery.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BatteryParams {
    pub cells: u32,
    pub capacity_ah: f64,
    pub internal_resistance_ohm: f64,
    pub table_state_of_charge: f64,
    pub ocv_soc: Vec<f64>,
    pub ocv_cell_v: Vec<f64>,
}

/// The energy-optimal polynomial trajectory (PTF) limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PtfParams {
    /// Limit on the speed along the path (3D).
    pub max_speed_m_s: f64,
    pub max_speed_xy_m_s: f64,
    pub max_speed_up_m_s: f64,
    pub max_speed_down_m_s: f64,
    /// How long the PTF's tracking controller lags its reference: the vehicle leaves hover this
    /// long after the operation starts (the paper's PTF is a PID loop following the polynomial,
    /// docs/energy-model.md). 0 for files written before it.
    #[serde(default)]
    pub tracking_lag_s: f64,
    pub steps: u32,
}

/// The high-velocity baseline (HVB).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HvbParams {
    pub speed_xy_m_s: f64,
    pub speed_up_m_s: f64,
    pub speed_down_m_s: f64,
    pub acceleration_m_s2: f64,
    pub settle_s: f64,
    pub steps: u32,
}

/// PX4 mission-mode trajectory parameters (PX4 parameter names, units in the key): what
/// `physics::px4` runs PX4's trajectory generator with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Px4Params {
    pub mpc_xy_cruise_m_s: f64,
    pub mpc_xy_vel_max_m_s: f64,
    pub mpc_z_v_auto_up_m_s: f64,
    pub mpc_z_v_auto_dn_m_s: f64,
    pub mpc_acc_hor_m_s2: f64,
    pub mpc_acc_up_max_m_s2: f64,
    pub mpc_acc_down_max_m_s2: f64,
    pub mpc_jerk_auto_m_s3: f64,
    pub mpc_xy_err_max_m: f64,
    pub mpc_tko_speed_m_s: f64,
    pub mpc_tko_ramp_t_s: f64,
    /// Vertical velocity gain (MPC_Z_VEL_P_ACC, 1/s): PX4's take-off ramp starts its upward
    /// velocity limit at -g / this (zero thrust) and raises it to MPC_TKO_SPEED over
    /// MPC_TKO_RAMP_T; the vehicle lifts off where the limit passes zero (thrust = weight).
    pub mpc_z_vel_p_acc_per_s: f64,
    pub mpc_land_speed_m_s: f64,
    pub mpc_land_alt1_m: f64,
    pub mpc_land_alt2_m: f64,
    pub mpc_z_vel_max_dn_m_s: f64,
    /// Landing crawl below MPC_LAND_ALT3, which PX4 does only with a distance sensor: 0 for a
    /// vehicle without one.
    pub mpc_land_alt3_m: f64,
    pub mpc_land_crwl_m_s: f64,
    /// Waypoint acceptance radius (NAV_ACC_RAD; what emplan sends as each item's param2).
    pub nav_acc_rad_m: f64,
    pub nav_mc_alt_rad_m: f64,
    /// The land detector's time from touchdown to a confirmed landing: PX4's
    /// MulticopterLandDetector holds ground contact, maybe-landed and landed in turn, each for
    /// its trigger time (constants in PX4's main branch, LNDMC_TRIG_TIME in some releases), the
    /// motors near idle meanwhile. Not read from the autopilot.
    #[serde(default = "default_land_detector_s")]
    pub land_detector_s: f64,
    /// How long PX4 stays armed on the ground once the landing is confirmed (COM_DISARM_LAND,
    /// commander's auto-disarm), the motors idling.
    #[serde(default = "default_com_disarm_land_s")]
    pub com_disarm_land_s: f64,
    /// How far above the home it took off from PX4 holds its home by the landing (m). PX4
    /// re-sets the home's altitude in flight (HomePosition, for baro drift), so the mission's
    /// last hover over the origin is this much higher, the landing schedule (MPC_LAND_ALT1,
    /// MPC_LAND_ALT2) counts heights from that home, and the descent goes on past it at
    /// MPC_LAND_SPEED to the ground. 0 (a vehicle file without it): the home stays put.
    #[serde(default)]
    pub landing_home_rise_m: f64,
    /// The vehicle's horizontal error behind its trajectory setpoint when it leaves a waypoint,
    /// closed exponentially with this time constant (not PX4 parameters: the vehicle's
    /// tracking, which slows PX4's trajectory through MPC_XY_ERR_MAX).
    pub departure_error_m: f64,
    pub departure_error_decay_s: f64,
    /// How much of `departure_error_m` a leg starting ahead of PX4's trajectory does not trail
    /// by (m; `physics::px4::Start::Ahead`: the vehicle left the last hold past its waypoint
    /// and the new leg turns less than 90 degrees, so it trails only once the trajectory has
    /// caught up with it). 0 (a vehicle file without it): priced as starting behind.
    #[serde(default)]
    pub departure_head_start_m: f64,
    pub steps: u32,
}

/// The land detector's time measured on PX4 SITL (1.1-1.3 s from ground contact to ON_GROUND),
/// for vehicle files written before the landing counted it.
fn default_land_detector_s() -> f64 {
    1.2
}

/// PX4's default COM_DISARM_LAND (commander_params.c).
fn default_com_disarm_land_s() -> f64 {
    2.0
}

/// A trajectory parameter the autopilot holds at another value than the vehicle file says.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamDifference {
    /// The autopilot's name for it.
    pub name: &'static str,
    /// The vehicle file's value ([px4] or [ardupilot]).
    pub file_value: f64,
    /// The autopilot's.
    pub autopilot_value: f64,
}

impl Px4Params {
    /// The parameters read from an autopilot (PX4 names; None: not answered) that differ from
    /// this set by more than float32 round-off (PARAM_VALUE carries a float32), in
    /// [`Px4Params::autopilot_values`]' order.
    pub fn differences(&self, read: &[(String, Option<f64>)]) -> Vec<ParamDifference> {
        differences(self.autopilot_values(), read)
    }

    /// The parameters the autopilot holds, by PX4 name (PX4's main branch as CI builds it; MPC_Z_V_AUTO_UP/DN
    /// were MPC_Z_VEL_MAX_UP/DN in auto modes before v1.14), with this set's values.
    pub fn autopilot_values(&self) -> Vec<(&'static str, f64)> {
        vec![
            ("MPC_XY_CRUISE", self.mpc_xy_cruise_m_s),
            ("MPC_XY_VEL_MAX", self.mpc_xy_vel_max_m_s),
            ("MPC_Z_V_AUTO_UP", self.mpc_z_v_auto_up_m_s),
            ("MPC_Z_V_AUTO_DN", self.mpc_z_v_auto_dn_m_s),
            ("MPC_ACC_HOR", self.mpc_acc_hor_m_s2),
            ("MPC_ACC_UP_MAX", self.mpc_acc_up_max_m_s2),
            ("MPC_ACC_DOWN_MAX", self.mpc_acc_down_max_m_s2),
            ("MPC_JERK_AUTO", self.mpc_jerk_auto_m_s3),
            ("MPC_XY_ERR_MAX", self.mpc_xy_err_max_m),
            ("MPC_TKO_SPEED", self.mpc_tko_speed_m_s),
            ("MPC_TKO_RAMP_T", self.mpc_tko_ramp_t_s),
            ("MPC_Z_VEL_P_ACC", self.mpc_z_vel_p_acc_per_s),
            ("MPC_LAND_SPEED", self.mpc_land_speed_m_s),
            ("MPC_LAND_ALT1", self.mpc_land_alt1_m),
            ("MPC_LAND_ALT2", self.mpc_land_alt2_m),
            ("MPC_LAND_ALT3", self.mpc_land_alt3_m),
            ("MPC_LAND_CRWL", self.mpc_land_crwl_m_s),
            ("MPC_Z_VEL_MAX_DN", self.mpc_z_vel_max_dn_m_s),
            ("NAV_ACC_RAD", self.nav_acc_rad_m),
            ("NAV_MC_ALT_RAD", self.nav_mc_alt_rad_m),
            ("COM_DISARM_LAND", self.com_disarm_land_s),
        ]
    }

    /// This set with the autopilot's values of the parameters named in `values` (PX4 names as
    /// [`Px4Params::autopilot_values`] gives them; other names and non-finite values are
    /// ignored).
    pub fn with_autopilot_values(&self, values: &[(String, f64)]) -> Px4Params {
        let mut p = self.clone();
        for (name, value) in values.iter().filter(|(_, v)| v.is_finite()) {
            let slot = match name.as_str() {
                "MPC_XY_CRUISE" => &mut p.mpc_xy_cruise_m_s,
                "MPC_XY_VEL_MAX" => &mut p.mpc_xy_vel_max_m_s,
                "MPC_Z_V_AUTO_UP" => &mut p.mpc_z_v_auto_up_m_s,
                "MPC_Z_V_AUTO_DN" => &mut p.mpc_z_v_auto_dn_m_s,
                "MPC_ACC_HOR" => &mut p.mpc_acc_hor_m_s2,
                "MPC_ACC_UP_MAX" => &mut p.mpc_acc_up_max_m_s2,
                "MPC_ACC_DOWN_MAX" => &mut p.mpc_acc_down_max_m_s2,
                "MPC_JERK_AUTO" => &mut p.mpc_jerk_auto_m_s3,
                "MPC_XY_ERR_MAX" => &mut p.mpc_xy_err_max_m,
                "MPC_TKO_SPEED" => &mut p.mpc_tko_speed_m_s,
                "MPC_TKO_RAMP_T" => &mut p.mpc_tko_ramp_t_s,
                "MPC_Z_VEL_P_ACC" => &mut p.mpc_z_vel_p_acc_per_s,
                "MPC_LAND_SPEED" => &mut p.mpc_land_speed_m_s,
                "MPC_LAND_ALT1" => &mut p.mpc_land_alt1_m,
                "MPC_LAND_ALT2" => &mut p.mpc_land_alt2_m,
                "MPC_LAND_ALT3" => &mut p.mpc_land_alt3_m,
                "MPC_LAND_CRWL" => &mut p.mpc_land_crwl_m_s,
                "MPC_Z_VEL_MAX_DN" => &mut p.mpc_z_vel_max_dn_m_s,
                "NAV_ACC_RAD" => &mut p.nav_acc_rad_m,
                "NAV_MC_ALT_RAD" => &mut p.nav_mc_alt_rad_m,
                "COM_DISARM_LAND" => &mut p.com_disarm_land_s,
                _ => continue,
            };
            *slot = *value;
        }
        p
    }
}

/// ArduCopter's AUTO-mode navigation, take-off and landing parameters (ArduCopter's names, in
/// the SI units its current build uses; the unit in each key): what `physics::ardupilot` flies
/// with. A vehicle file without an `[ardupilot]` section gets ArduCopter's defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArdupilotParams {
    pub wp_spd_m_s: f64,
    pub wp_spd_up_m_s: f64,
    pub wp_spd_dn_m_s: f64,
    pub wp_acc_m_s2: f64,
    pub wp_acc_z_m_s2: f64,
    pub wp_jerk_m_s3: f64,
    pub wp_radius_m: f64,
    /// The attitude controller's input time constant and rate and angular-acceleration limits
    /// (0: none), which bound the waypoint S-curve's jerk and snap.
    pub atc_input_tc_s: f64,
    pub atc_rate_r_max_deg_s: f64,
    pub atc_rate_p_max_deg_s: f64,
    pub atc_acc_r_max_deg_s2: f64,
    pub atc_acc_p_max_deg_s2: f64,
    /// The vertical position controller's jerk (shaping take-off and landing) and position
    /// gain (the landing's approach to LAND_ALT_LOW_M).
    pub psc_jerk_d_m_s3: f64,
    pub psc_d_pos_p: f64,
    pub land_spd_m_s: f64,
    /// 0: WP_SPD_DN.
    pub land_spd_high_m_s: f64,
    pub land_alt_low_m: f64,
    /// How long a waypoint leg takes beyond its S-curve, priced as hover before it moves:
    /// ArduCopter slows the S-curve's clock while the vehicle trails its target
    /// (AC_WPNav.cpp `advance_wp_target_along_track`, `_track_scalar_dt`), by how much the
    /// vehicle's response decides, which is not modelled; calibrated (see vehicle.toml).
    pub tracking_lag_s: f64,
    pub steps: u32,
}

/// [`ArdupilotParams::tracking_lag_s`] of ArduCopter SITL's S1000-like frame, calibrated
/// against its leg durations (the two paper samples' flights).
pub const TRACKING_LAG_S: f64 = 0.68;

impl Default for ArdupilotParams {
    /// ArduCopter's defaults (libraries/AC_WPNav/AC_WPNav.cpp, AC_AttitudeControl_Multi.cpp,
    /// AC_PosControl.cpp, ArduCopter/Parameters.cpp), as ArduCopter SITL reads them back.
    fn default() -> Self {
        ArdupilotParams {
            wp_spd_m_s: 10.0,
            wp_spd_up_m_s: 2.5,
            wp_spd_dn_m_s: 1.5,
            wp_acc_m_s2: 2.5,
            wp_acc_z_m_s2: 1.0,
            wp_jerk_m_s3: 1.0,
            wp_radius_m: 2.0,
            atc_input_tc_s: 0.15,
            atc_rate_r_max_deg_s: 0.0,
            atc_rate_p_max_deg_s: 0.0,
            atc_acc_r_max_deg_s2: 1100.0,
            atc_acc_p_max_deg_s2: 1100.0,
            psc_jerk_d_m_s3: 5.0,
            psc_d_pos_p: 1.0,
            land_spd_m_s: 0.5,
            land_spd_high_m_s: 0.0,
            land_alt_low_m: 10.0,
            // Calibrated against ArduCopter SITL: the mean of the leg durations measured less
            // the S-curve's over the two paper samples' flights (docs/ardupilot-sitl.md).
            tracking_lag_s: TRACKING_LAG_S,
            steps: 200,
        }
    }
}

impl ArdupilotParams {
    /// The parameters the autopilot holds, by ArduCopter's name (its build of 2026-04, where
    /// WPNAV_SPEED became WP_SPD in m/s and LAND_SPEED LAND_SPD_MS), with this set's values.
    pub fn autopilot_values(&self) -> Vec<(&'static str, f64)> {
        vec![
            ("WP_SPD", self.wp_spd_m_s),
            ("WP_SPD_UP", self.wp_spd_up_m_s),
            ("WP_SPD_DN", self.wp_spd_dn_m_s),
            ("WP_ACC", self.wp_acc_m_s2),
            ("WP_ACC_Z", self.wp_acc_z_m_s2),
            ("WP_JERK", self.wp_jerk_m_s3),
            ("WP_RADIUS_M", self.wp_radius_m),
            ("ATC_INPUT_TC", self.atc_input_tc_s),
            ("ATC_RATE_R_MAX", self.atc_rate_r_max_deg_s),
            ("ATC_RATE_P_MAX", self.atc_rate_p_max_deg_s),
            ("ATC_ACC_R_MAX", self.atc_acc_r_max_deg_s2),
            ("ATC_ACC_P_MAX", self.atc_acc_p_max_deg_s2),
            ("PSC_JERK_D", self.psc_jerk_d_m_s3),
            ("PSC_D_POS_P", self.psc_d_pos_p),
            ("LAND_SPD_MS", self.land_spd_m_s),
            ("LAND_SPD_HIGH_MS", self.land_spd_high_m_s),
            ("LAND_ALT_LOW_M", self.land_alt_low_m),
        ]
    }

    /// The parameters read from an autopilot that differ from this set (as
    /// [`Px4Params::differences`]).
    pub fn differences(&self, read: &[(String, Option<f64>)]) -> Vec<ParamDifference> {
        differences(self.autopilot_values(), read)
    }

    /// This set with the autopilot's values of the parameters named in `values` (ArduCopter
    /// names; other names and non-finite values are ignored).
    pub fn with_autopilot_values(&self, values: &[(String, f64)]) -> ArdupilotParams {
        let mut p = self.clone();
        for (name, value) in values.iter().filter(|(_, v)| v.is_finite()) {
            let slot = match name.as_str() {
                "WP_SPD" => &mut p.wp_spd_m_s,
                "WP_SPD_UP" => &mut p.wp_spd_up_m_s,
                "WP_SPD_DN" => &mut p.wp_spd_dn_m_s,
                "WP_ACC" => &mut p.wp_acc_m_s2,
                "WP_ACC_Z" => &mut p.wp_acc_z_m_s2,
                "WP_JERK" => &mut p.wp_jerk_m_s3,
                "WP_RADIUS_M" => &mut p.wp_radius_m,
                "ATC_INPUT_TC" => &mut p.atc_input_tc_s,
                "ATC_RATE_R_MAX" => &mut p.atc_rate_r_max_deg_s,
                "ATC_RATE_P_MAX" => &mut p.atc_rate_p_max_deg_s,
                "ATC_ACC_R_MAX" => &mut p.atc_acc_r_max_deg_s2,
                "ATC_ACC_P_MAX" => &mut p.atc_acc_p_max_deg_s2,
                "PSC_JERK_D" => &mut p.psc_jerk_d_m_s3,
                "PSC_D_POS_P" => &mut p.psc_d_pos_p,
                "LAND_SPD_MS" => &mut p.land_spd_m_s,
                "LAND_SPD_HIGH_MS" => &mut p.land_spd_high_m_s,
                "LAND_ALT_LOW_M" => &mut p.land_alt_low_m,
                _ => continue,
            };
            *slot = *value;
        }
        p
    }
}

/// The parameters read (None: not answered) that differ from `values` by more than float32
/// round-off (PARAM_VALUE carries a float32), in `values`' order.
fn differences(
    values: Vec<(&'static str, f64)>,
    read: &[(String, Option<f64>)],
) -> Vec<ParamDifference> {
    values
        .into_iter()
        .filter_map(|(name, file_value)| {
            let autopilot_value = read
                .iter()
                .find(|(n, _)| n == name)
                .and_then(|(_, v)| *v)
                .filter(|v| v.is_finite())?;
            let tolerance = 1e-5 * file_value.abs().max(1.0);
            ((autopilot_value - file_value).abs() > tolerance).then_some(ParamDifference {
                name,
                file_value,
                autopilot_value,
            })
        })
        .collect()
}

/// A vehicle: everything the energy model needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vehicle {
    pub name: String,
    pub planning: Planning,
    pub body: Body,
    pub rotor: RotorParams,
    pub motor: MotorParams,
    pub battery: BatteryParams,
    pub ptf: PtfParams,
    pub hvb: HvbParams,
    pub px4: Px4Params,
    #[serde(default)]
    pub ardupilot: ArdupilotParams,
}

impl Vehicle {
    /// Reads and validates `<dir>/vehicle.toml`.
    pub fn load(dir: &Path) -> Result<Vehicle, PhysicsError> {
        let path = dir.join("vehicle.toml");
        let file = path.display().to_string();
        let text = std::fs::read_to_string(&path).map_err(|e| PhysicsError::Io {
            file: file.clone(),
            source_text: e.to_string(),
        })?;
        Self::from_toml(&text, &file)
    }

    /// Parses and validates vehicle TOML; `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Vehicle, PhysicsError> {
        let vehicle: Vehicle = toml::from_str(text).map_err(|e| PhysicsError::VehicleFile {
            file: file.to_string(),
            line: e.span().map_or(String::new(), |s| {
                format!(" line {}:", line_of(text, s.start))
            }),
            key: "toml".to_string(),
            problem: e.message().trim().to_string(),
        })?;
        vehicle.validate(file)?;
        Ok(vehicle)
    }

    /// Every parameter within its physical range, or an error naming `file` and the key.
    pub fn validate(&self, file: &str) -> Result<(), PhysicsError> {
        let fail = |key: &str, problem: String| PhysicsError::VehicleFile {
            file: file.to_string(),
            line: String::new(),
            key: key.to_string(),
            problem,
        };
        let check = |key: &str, value: f64, lo: f64, hi: f64| {
            if value.is_finite() && value >= lo && value <= hi {
                Ok(())
            } else {
                Err(fail(
                    key,
                    format!("{value} is out of range (allowed: {lo} to {hi})"),
                ))
            }
        };
        let p = &self.planning;
        check(
            "planning.usable_energy_wh",
            p.usable_energy_wh,
            1.0,
            100_000.0,
        )?;
        check("planning.reserve_pct", p.reserve_pct, 0.0, 90.0)?;
        check(
            "planning.max_height_above_home_m",
            p.max_height_above_home_m,
            1.0,
            10_000.0,
        )?;
        check("planning.max_leg_m", p.max_leg_m, 1.0, 100_000.0)?;
        check("planning.max_speed_m_s", p.max_speed_m_s, 0.5, 100.0)?;
        // No profile may plan faster than the vehicle can fly.
        for (key, speed) in [
            ("ptf.max_speed_xy_m_s", self.ptf.max_speed_xy_m_s),
            ("hvb.speed_xy_m_s", self.hvb.speed_xy_m_s),
            ("px4.mpc_xy_cruise_m_s", self.px4.mpc_xy_cruise_m_s),
        ] {
            if speed > p.max_speed_m_s {
                return Err(fail(
                    key,
                    format!(
                        "{speed} m/s is above the vehicle's planning.max_speed_m_s of {} m/s",
                        p.max_speed_m_s
                    ),
                ));
            }
        }
        let b = &self.body;
        check("body.mass_kg", b.mass_kg, 0.1, 200.0)?;
        check("body.gravity_m_s2", b.gravity_m_s2, 9.7, 9.9)?;
        check("body.air_density_kg_m3", b.air_density_kg_m3, 0.5, 1.5)?;
        check(
            "body.drag_coefficient_n_s2_m2",
            b.drag_coefficient_n_s2_m2,
            0.0,
            10.0,
        )?;
        check(
            "body.vertical_drag_coefficient_n_s2_m2",
            b.vertical_drag_coefficient_n_s2_m2,
            0.0,
            10.0,
        )?;
        check("body.avionics_power_w", b.avionics_power_w, 0.0, 1000.0)?;
        check("body.max_tilt_deg", b.max_tilt_deg, 5.0, 70.0)?;
        let r = &self.rotor;
        check("rotor.count", f64::from(r.count), 1.0, 32.0)?;
        check("rotor.blades", f64::from(r.blades), 2.0, 8.0)?;
        check("rotor.radius_m", r.radius_m, 0.01, 5.0)?;
        check(
            "rotor.root_cutout_m",
            r.root_cutout_m,
            0.0,
            0.5 * r.radius_m,
        )?;
        check("rotor.tip_loss_factor", r.tip_loss_factor, 0.8, 1.0)?;
        check("rotor.chord_m", r.chord_m, 0.001, 0.5 * r.radius_m)?;
        check(
            "rotor.geometric_pitch_m",
            r.geometric_pitch_m,
            0.001,
            10.0 * r.radius_m,
        )?;
        check(
            "rotor.collective_offset_deg",
            r.collective_offset_deg,
            -10.0,
            10.0,
        )?;
        check("rotor.lift_slope_per_rad", r.lift_slope_per_rad, 1.0, 7.0)?;
        check("rotor.drag_coefficient", r.drag_coefficient, 0.0, 0.2)?;
        check(
            "rotor.induced_power_factor",
            r.induced_power_factor,
            1.0,
            1.5,
        )?;
        check(
            "rotor.descent_inflow_factor",
            r.descent_inflow_factor,
            0.0,
            1.0,
        )?;
        check("rotor.airflow_factor", r.airflow_factor, 0.0, 1.0)?;
        let m = &self.motor;
        check("motor.kv_rpm_per_v", m.kv_rpm_per_v, 10.0, 10_000.0)?;
        check("motor.resistance_ohm", m.resistance_ohm, 0.0, 10.0)?;
        check("motor.no_load_current_a", m.no_load_current_a, 0.0, 20.0)?;
        check("motor.esc_efficiency", m.esc_efficiency, 0.5, 1.0)?;
        let bat = &self.battery;
        check("battery.cells", f64::from(bat.cells), 1.0, 24.0)?;
        check("battery.capacity_ah", bat.capacity_ah, 0.1, 1000.0)?;
        check(
            "battery.internal_resistance_ohm",
            bat.internal_resistance_ohm,
            0.0,
            1.0,
        )?;
        check(
            "battery.table_state_of_charge",
            bat.table_state_of_charge,
            0.0,
            1.0,
        )?;
        if bat.ocv_soc.len() < 2 || bat.ocv_soc.len() != bat.ocv_cell_v.len() {
            return Err(fail(
                "battery.ocv_soc",
                "needs at least 2 points and as many as battery.ocv_cell_v".into(),
            ));
        }
        if !bat.ocv_soc.windows(2).all(|w| w[0] < w[1]) {
            return Err(fail(
                "battery.ocv_soc",
                "must be strictly increasing".into(),
            ));
        }
        for &v in &bat.ocv_cell_v {
            check("battery.ocv_cell_v", v, 2.5, 4.5)?;
        }
        let t = &self.ptf;
        check("ptf.max_speed_m_s", t.max_speed_m_s, 0.5, 40.0)?;
        check("ptf.max_speed_xy_m_s", t.max_speed_xy_m_s, 0.5, 40.0)?;
        check("ptf.max_speed_up_m_s", t.max_speed_up_m_s, 0.2, 20.0)?;
        check("ptf.max_speed_down_m_s", t.max_speed_down_m_s, 0.2, 20.0)?;
        check("ptf.tracking_lag_s", t.tracking_lag_s, 0.0, 10.0)?;
        check("ptf.steps", f64::from(t.steps), 20.0, 100_000.0)?;
        let h = &self.hvb;
        check("hvb.speed_xy_m_s", h.speed_xy_m_s, 0.5, 40.0)?;
        check("hvb.speed_up_m_s", h.speed_up_m_s, 0.2, 20.0)?;
        check("hvb.speed_down_m_s", h.speed_down_m_s, 0.2, 20.0)?;
        check("hvb.acceleration_m_s2", h.acceleration_m_s2, 0.2, 20.0)?;
        check("hvb.settle_s", h.settle_s, 0.0, 60.0)?;
        check("hvb.steps", f64::from(h.steps), 20.0, 100_000.0)?;
        let x = &self.px4;
        check("px4.mpc_xy_cruise_m_s", x.mpc_xy_cruise_m_s, 0.5, 40.0)?;
        check("px4.mpc_z_v_auto_up_m_s", x.mpc_z_v_auto_up_m_s, 0.2, 20.0)?;
        check("px4.mpc_z_v_auto_dn_m_s", x.mpc_z_v_auto_dn_m_s, 0.2, 20.0)?;
        check("px4.mpc_acc_hor_m_s2", x.mpc_acc_hor_m_s2, 0.2, 20.0)?;
        check("px4.mpc_acc_up_max_m_s2", x.mpc_acc_up_max_m_s2, 0.2, 20.0)?;
        check(
            "px4.mpc_acc_down_max_m_s2",
            x.mpc_acc_down_max_m_s2,
            0.2,
            20.0,
        )?;
        check("px4.mpc_jerk_auto_m_s3", x.mpc_jerk_auto_m_s3, 0.2, 100.0)?;
        check("px4.mpc_xy_vel_max_m_s", x.mpc_xy_vel_max_m_s, 0.5, 40.0)?;
        check("px4.mpc_xy_err_max_m", x.mpc_xy_err_max_m, 0.0, 100.0)?;
        check("px4.mpc_tko_speed_m_s", x.mpc_tko_speed_m_s, 0.1, 20.0)?;
        check("px4.mpc_tko_ramp_t_s", x.mpc_tko_ramp_t_s, 0.1, 60.0)?;
        check(
            "px4.mpc_z_vel_p_acc_per_s",
            x.mpc_z_vel_p_acc_per_s,
            0.5,
            30.0,
        )?;
        check("px4.mpc_land_speed_m_s", x.mpc_land_speed_m_s, 0.1, 20.0)?;
        check("px4.mpc_land_alt1_m", x.mpc_land_alt1_m, 0.0, 1000.0)?;
        check(
            "px4.mpc_land_alt2_m",
            x.mpc_land_alt2_m,
            0.0,
            x.mpc_land_alt1_m,
        )?;
        check(
            "px4.mpc_z_vel_max_dn_m_s",
            x.mpc_z_vel_max_dn_m_s,
            0.1,
            20.0,
        )?;
        check(
            "px4.mpc_land_alt3_m",
            x.mpc_land_alt3_m,
            0.0,
            x.mpc_land_alt2_m,
        )?;
        check("px4.mpc_land_crwl_m_s", x.mpc_land_crwl_m_s, 0.05, 20.0)?;
        check("px4.nav_acc_rad_m", x.nav_acc_rad_m, 0.05, 200.0)?;
        check("px4.nav_mc_alt_rad_m", x.nav_mc_alt_rad_m, 0.05, 200.0)?;
        check("px4.land_detector_s", x.land_detector_s, 0.0, 60.0)?;
        check("px4.com_disarm_land_s", x.com_disarm_land_s, 0.0, 600.0)?;
        check(
            "px4.landing_home_rise_m",
            x.landing_home_rise_m,
            -10.0,
            10.0,
        )?;
        check("px4.departure_error_m", x.departure_error_m, 0.0, 100.0)?;
        check(
            "px4.departure_head_start_m",
            x.departure_head_start_m,
            0.0,
            x.departure_error_m.max(0.0),
        )?;
        check(
            "px4.departure_error_decay_s",
            x.departure_error_decay_s,
            0.01,
            600.0,
        )?;
        check("px4.steps", f64::from(x.steps), 20.0, 100_000.0)?;
        let a = &self.ardupilot;
        for (key, value, lo, hi) in [
            ("ardupilot.wp_spd_m_s", a.wp_spd_m_s, 0.2, 20.0),
            ("ardupilot.wp_spd_up_m_s", a.wp_spd_up_m_s, 0.1, 10.0),
            ("ardupilot.wp_spd_dn_m_s", a.wp_spd_dn_m_s, 0.1, 5.0),
            ("ardupilot.wp_acc_m_s2", a.wp_acc_m_s2, 0.5, 5.0),
            ("ardupilot.wp_acc_z_m_s2", a.wp_acc_z_m_s2, 0.5, 5.0),
            ("ardupilot.wp_jerk_m_s3", a.wp_jerk_m_s3, 0.5, 20.0),
            ("ardupilot.wp_radius_m", a.wp_radius_m, 0.05, 10.0),
            ("ardupilot.atc_input_tc_s", a.atc_input_tc_s, 0.0, 1.0),
            (
                "ardupilot.atc_rate_r_max_deg_s",
                a.atc_rate_r_max_deg_s,
                0.0,
                1080.0,
            ),
            (
                "ardupilot.atc_rate_p_max_deg_s",
                a.atc_rate_p_max_deg_s,
                0.0,
                1080.0,
            ),
            (
                "ardupilot.atc_acc_r_max_deg_s2",
                a.atc_acc_r_max_deg_s2,
                0.0,
                1800.0,
            ),
            (
                "ardupilot.atc_acc_p_max_deg_s2",
                a.atc_acc_p_max_deg_s2,
                0.0,
                1800.0,
            ),
            ("ardupilot.psc_jerk_d_m_s3", a.psc_jerk_d_m_s3, 0.5, 50.0),
            ("ardupilot.psc_d_pos_p", a.psc_d_pos_p, 0.1, 10.0),
            ("ardupilot.land_spd_m_s", a.land_spd_m_s, 0.3, 2.0),
            ("ardupilot.land_spd_high_m_s", a.land_spd_high_m_s, 0.0, 5.0),
            ("ardupilot.land_alt_low_m", a.land_alt_low_m, 1.0, 100.0),
            ("ardupilot.tracking_lag_s", a.tracking_lag_s, 0.0, 10.0),
            ("ardupilot.steps", f64::from(a.steps), 20.0, 100_000.0),
        ] {
            check(key, value, lo, hi)?;
        }
        Ok(())
    }

    /// The horizontal speed the autopilot flies a mission at unless told otherwise: ArduPilot's
    /// WP_SPD (`ardupilot`), else PX4's MPC_XY_CRUISE.
    pub fn cruise_speed_m_s(&self, ardupilot: bool) -> f64 {
        if ardupilot {
            self.ardupilot.wp_spd_m_s
        } else {
            self.px4.mpc_xy_cruise_m_s
        }
    }

    /// The vehicle flying its missions at `speed_m_s` (a DO_CHANGE_SPEED): every profile's
    /// horizontal cruise speed set to it, as the autopilots do (PX4 MPC_XY_CRUISE, ArduPilot
    /// WP_SPD; the paper's profiles' horizontal speed limits).
    pub fn at_speed(&self, speed_m_s: f64) -> Vehicle {
        let mut v = self.clone();
        v.px4.mpc_xy_cruise_m_s = speed_m_s;
        v.ardupilot.wp_spd_m_s = speed_m_s;
        v.hvb.speed_xy_m_s = speed_m_s;
        v.ptf.max_speed_xy_m_s = speed_m_s;
        v
    }

    /// The profile planning uses unless the user overrides it.
    pub fn default_profile(&self) -> Profile {
        self.planning.default_profile
    }

    /// Usable battery energy after the reserve, in joules.
    pub fn mission_budget_j(&self) -> f64 {
        self.planning.usable_energy_wh * 3600.0 * (1.0 - self.planning.reserve_pct / 100.0)
    }

    /// Open-circuit pack voltage at a state of charge (linear interpolation of the cell curve).
    pub fn open_circuit_voltage_v(&self, soc: f64) -> f64 {
        let b = &self.battery;
        let soc = soc.clamp(b.ocv_soc[0], b.ocv_soc[b.ocv_soc.len() - 1]);
        let k = b
            .ocv_soc
            .windows(2)
            .position(|w| soc <= w[1])
            .unwrap_or(b.ocv_soc.len() - 2);
        let (s0, s1) = (b.ocv_soc[k], b.ocv_soc[k + 1]);
        let (v0, v1) = (b.ocv_cell_v[k], b.ocv_cell_v[k + 1]);
        f64::from(b.cells) * (v0 + (v1 - v0) * (soc - s0) / (s1 - s0))
    }

    /// A fingerprint of everything a `profile` table depends on (FNV-1a over the canonical JSON
    /// of the physics sections and that profile's section), recorded in table headers.
    pub fn parameter_hash(&self, profile: Profile) -> String {
        let profile_json = match profile {
            Profile::Ptf => serde_json::to_string(&self.ptf),
            Profile::Hvb => serde_json::to_string(&self.hvb),
            Profile::Px4 => serde_json::to_string(&self.px4),
            Profile::Ardupilot => serde_json::to_string(&self.ardupilot),
        };
        let canonical =
            serde_json::to_string(&(&self.body, &self.rotor, &self.motor, &self.battery))
                .unwrap_or_default()
                + &profile_json.unwrap_or_default();
        let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
        for byte in canonical.bytes() {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
        format!("{hash:016x}")
    }
}

#[cfg(test)]
pub(crate) fn shipped() -> Vehicle {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    Vehicle::load(&dir).expect("the shipped vehicle loads")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_vehicle_loads_and_plans_with_px4_by_default() {
        let v = shipped();
        assert_eq!(v.default_profile(), Profile::Px4);
        assert!((v.open_circuit_voltage_v(1.0) - 25.2).abs() < 1e-9);
        assert!((v.open_circuit_voltage_v(0.55) - 6.0 * 3.855).abs() < 1e-9);
    }

    #[test]
    fn an_out_of_range_parameter_is_rejected_naming_its_key() {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/vehicle.toml"),
        )
        .unwrap();
        let bad = text.replace("radius_m = 0.1905", "radius_m = -1.0");
        let err = Vehicle::from_toml(&bad, "v.toml").unwrap_err().to_string();
        assert!(
            err.contains("rotor.radius_m") && err.contains("out of range"),
            "{err}"
        );
        let bad = text.replace("[body]\n", "[body]\nmass_lb = 13.2\n");
        let err = Vehicle::from_toml(&bad, "v.toml").unwrap_err().to_string();
        assert!(
            err.contains("v.toml") && err.contains("unknown field"),
            "{err}"
        );
    }

    #[test]
    fn ardupilot_parameters_map_to_the_ardupilot_section_by_their_names_and_are_validated() {
        let v = shipped();
        assert_eq!(v.ardupilot, ArdupilotParams::default());
        let named = v.ardupilot.autopilot_values();
        assert_eq!(named.len(), 17);
        let same: Vec<(String, f64)> = named.iter().map(|(n, x)| (n.to_string(), *x)).collect();
        assert_eq!(v.ardupilot.with_autopilot_values(&same), v.ardupilot);
        let read = vec![
            ("WP_SPD".to_string(), Some(5.0)),
            ("LAND_SPD_MS".to_string(), Some(0.5)),
            ("WP_JERK".to_string(), None),
        ];
        let diff = v.ardupilot.differences(&read);
        assert_eq!(diff.len(), 1);
        assert_eq!(
            (diff[0].name, diff[0].file_value, diff[0].autopilot_value),
            ("WP_SPD", 10.0, 5.0)
        );
        let slower = v.ardupilot.with_autopilot_values(&[
            ("WP_SPD".to_string(), 5.0),
            ("MPC_XY_CRUISE".to_string(), 1.0),
        ]);
        assert_eq!(slower.wp_spd_m_s, 5.0);
        // A vehicle file without [ardupilot] gets ArduCopter's defaults; a bad value is refused
        // naming its key.
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/vehicle.toml"),
        )
        .unwrap();
        let cut = text.find("[ardupilot]").unwrap();
        let without = Vehicle::from_toml(&text[..cut], "v.toml").unwrap();
        assert_eq!(without.ardupilot, ArdupilotParams::default());
        let bad = text.replace("wp_acc_z_m_s2 = 1.0", "wp_acc_z_m_s2 = 0.0");
        let err = Vehicle::from_toml(&bad, "v.toml").unwrap_err().to_string();
        assert!(err.contains("ardupilot.wp_acc_z_m_s2"), "{err}");
    }

    #[test]
    fn px4_parameters_map_to_the_px4_section_by_their_px4_names_both_ways() {
        let v = shipped();
        let named = v.px4.autopilot_values();
        assert_eq!(named.len(), 21);
        // Read back unchanged, every name lands on its own key.
        let same: Vec<(String, f64)> = named.iter().map(|(n, x)| (n.to_string(), *x)).collect();
        assert_eq!(v.px4.with_autopilot_values(&same), v.px4);
        for (k, (name, value)) in named.iter().enumerate() {
            let changed = v
                .px4
                .with_autopilot_values(&[(name.to_string(), value + 1.0)])
                .autopilot_values();
            for (j, (_, x)) in changed.iter().enumerate() {
                let want = if j == k { value + 1.0 } else { named[j].1 };
                assert_eq!(*x, want, "{name} moved {}", named[j].0);
            }
        }
        let ignored = v.px4.with_autopilot_values(&[
            ("SYS_AUTOSTART".into(), 4001.0),
            ("MPC_XY_CRUISE".into(), f64::NAN),
        ]);
        assert_eq!(ignored, v.px4);
    }

    #[test]
    fn only_parameters_read_off_by_more_than_float32_round_off_differ() {
        let p = shipped().px4;
        let read = vec![
            // As a float32 carries it: not a difference.
            (
                "MPC_XY_CRUISE".to_string(),
                Some(f64::from(p.mpc_xy_cruise_m_s as f32)),
            ),
            ("MPC_ACC_HOR".to_string(), Some(p.mpc_acc_hor_m_s2 + 0.5)),
            ("NAV_ACC_RAD".to_string(), Some(p.nav_acc_rad_m * 2.0)),
            // Unanswered, or not one of ours: nothing to compare.
            ("MPC_JERK_AUTO".to_string(), None),
            ("SYS_AUTOSTART".to_string(), Some(4001.0)),
        ];
        let d = p.differences(&read);
        let named: Vec<(&str, f64, f64)> = d
            .iter()
            .map(|x| (x.name, x.file_value, x.autopilot_value))
            .collect();
        assert_eq!(
            named,
            [
                ("MPC_ACC_HOR", p.mpc_acc_hor_m_s2, p.mpc_acc_hor_m_s2 + 0.5),
                ("NAV_ACC_RAD", p.nav_acc_rad_m, p.nav_acc_rad_m * 2.0),
            ]
        );
    }

    #[test]
    fn the_parameter_hash_changes_with_physics_but_not_with_planning_or_other_profiles() {
        let v = shipped();
        let mut heavier = v.clone();
        heavier.body.mass_kg += 0.1;
        assert_ne!(
            v.parameter_hash(Profile::Ptf),
            heavier.parameter_hash(Profile::Ptf)
        );
        let mut planning = v.clone();
        planning.planning.reserve_pct = 30.0;
        planning.hvb.settle_s = 3.0;
        assert_eq!(
            v.parameter_hash(Profile::Ptf),
            planning.parameter_hash(Profile::Ptf)
        );
        assert_ne!(
            v.parameter_hash(Profile::Hvb),
            planning.parameter_hash(Profile::Hvb)
        );
    }
}
