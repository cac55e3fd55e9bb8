//! The parameter server: PX4 answers PARAM_REQUEST_READ with the trajectory parameters it holds
//! (the vehicle's [px4] section, by PX4 name), the ArduPilot flavour with its navigation
//! parameters (the vehicle's [ardupilot] section, by ArduCopter name). Both
//! hold their return altitude, 0: the mock's return flies home at the height it is at (PX4
//! RTL_RETURN_ALT and ArduCopter RTL_ALT at 0 do the same above a point higher than them).

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
    params
}

impl<'v> SimVehicle<'v> {
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
