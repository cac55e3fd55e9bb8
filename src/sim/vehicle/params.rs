//! The parameter server: PX4 answers PARAM_REQUEST_READ with the trajectory parameters it holds
//! (the vehicle's [px4] section, by PX4 name), the ArduPilot flavour with its navigation
//! parameters (the vehicle's [ardupilot] section, by ArduCopter name). Both
//! hold their return altitude, 0: the mock's return flies home at the height it is at (PX4
//! RTL_RETURN_ALT and ArduCopter RTL_ALT at 0 do the same above a point higher than them),
//! and the parameters of where it returns to (ArduPilot RALLY_LIMIT_KM and RALLY_INCL_HOME, PX4
//! RTL_TYPE) at their defaults.

use super::SimVehicle;

use crate::link::mav::MavMessage;
use crate::link::Flavour;
use crate::physics::Vehicle;

/// The parameters a mock of `flavour` flying `vehicle` answers.
pub(super) fn held(flavour: Flavour, vehicle: &Vehicle) -> Vec<(&'static str, f64)> {
    let mut params = match flavour {
        Flavour::ArduPilot => vehicle.ardupilot.autopilot_values(),
        Flavour::Px4 | Flavour::Generic => vehicle.px4.autopilot_values(),
    };
    params.push((crate::link::params::ReturnAltitude::of(flavour).name, 0.0));
    // Where the return goes (mission::fence::ReturnRule), at the autopilot's defaults.
    match flavour {
        Flavour::ArduPilot => {
            use crate::mission::fence::{ARDUCOPTER_RALLY_INCL_HOME, ARDUCOPTER_RALLY_LIMIT_KM};
            params.push(("RALLY_LIMIT_KM", ARDUCOPTER_RALLY_LIMIT_KM));
            params.push((
                "RALLY_INCL_HOME",
                f64::from(u8::from(ARDUCOPTER_RALLY_INCL_HOME)),
            ));
        }
        Flavour::Px4 => params.push(("RTL_TYPE", f64::from(crate::mission::fence::PX4_RTL_TYPE))),
        Flavour::Generic => {}
    }
    params
}

impl<'v> SimVehicle<'v> {
    /// The parameter `name` as it holds it.
    pub(super) fn param(&self, name: &str) -> Option<f64> {
        self.params
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| *v)
    }

    /// PX4 answers PARAM_REQUEST_READ by name (index -1) or by index with PARAM_VALUE, and an
    /// unknown name with nothing (mavlink_parameters.cpp); the ArduPilot flavour the same with
    /// its own names.
    pub(super) fn param_value(
        &mut self,
        _from: (u8, u8),
        request: &crate::link::mav::PARAM_REQUEST_READ_DATA,
    ) -> Vec<MavMessage> {
        let for_us = request.target_system == self.system_id
            && (request.target_component == 0 || request.target_component == self.component_id);
        if !for_us {
            return Vec::new();
        }
        let index = if request.param_index < 0 {
            let Ok(name) = request.param_id.to_str() else {
                return Vec::new();
            };
            self.params.iter().position(|(n, _)| *n == name)
        } else {
            usize::try_from(request.param_index)
                .ok()
                .filter(|&k| k < self.params.len())
        };
        let Some(k) = index else {
            return Vec::new();
        };
        let (name, value) = self.params[k];
        let mut answer = crate::link::params::encode(
            self.flavour,
            name,
            value,
            crate::link::mav::MavParamType::MAV_PARAM_TYPE_REAL32,
        );
        if let MavMessage::PARAM_VALUE(p) = &mut answer {
            p.param_count = self.params.len() as u16;
            p.param_index = k as u16;
        }
        self.out.push(answer);
        self.take_out()
    }
}
