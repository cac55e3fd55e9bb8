//! The parameter server: PX4 answers PARAM_REQUEST_READ with the trajectory parameters it holds
//! (the vehicle's [px4] section, by PX4 name); the ArduPilot flavour holds none of them.

use super::SimVehicle;

use crate::link::mav::MavMessage;
use crate::link::Flavour;

impl<'v> SimVehicle<'v> {
    /// PX4 answers PARAM_REQUEST_READ by name (index -1) or by index with PARAM_VALUE, and an
    /// unknown name with nothing (mavlink_parameters.cpp); the ArduPilot flavour holds none of
    /// these names.
    pub(super) fn param_value(
        &mut self,
        _from: (u8, u8),
        request: &crate::link::mav::PARAM_REQUEST_READ_DATA,
    ) -> Vec<MavMessage> {
        let for_us = request.target_system == self.system_id
            && (request.target_component == 0 || request.target_component == self.component_id);
        if !for_us || self.flavour == Flavour::ArduPilot {
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
