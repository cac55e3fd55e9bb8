//! Raw MAVLink frames to messages and back, and the checksum that tells a whole frame from a
//! corrupt span of a recording.

use mavlink::{MavHeader, MavlinkReader, MavlinkVersion};

use crate::flightlog::tlog::FrameCheck;
use crate::flightlog::FlightLogError;
use crate::link::mav::MavMessage;

/// Errors at the telemetry edge.
#[derive(Debug, thiserror::Error)]
pub enum TelemetryError {
    #[error("frame of {len} bytes: {reason}")]
    Frame { len: usize, reason: String },
    #[error(transparent)]
    Log(#[from] FlightLogError),
}

/// Judges a whole raw frame for [`TlogReader::resynchronising`]: its checksum with the
/// ardupilotmega dialect's CRC_EXTRA for its message id (mavlink.io, "Serialization: CRC_EXTRA").
pub fn check_frame(frame: &[u8]) -> FrameCheck {
    use mavlink::Message;
    // Where the message id is and where the checksummed bytes (after the start byte) end.
    let (id, crc_end) = match (frame.first(), frame.get(1), frame.get(2)) {
        (Some(0xFE), Some(&len), _) if frame.len() > 5 => {
            (u32::from(frame[5]), 6 + usize::from(len))
        }
        (Some(0xFD), Some(&len), Some(&flags)) => {
            let id_at = if flags & 0x02 != 0 { 10 } else { 7 };
            let Some(id) = frame.get(id_at..id_at + 3) else {
                return FrameCheck::BadCrc;
            };
            (
                u32::from_le_bytes([id[0], id[1], id[2], 0]),
                id_at + 3 + usize::from(len),
            )
        }
        _ => return FrameCheck::BadCrc,
    };
    let Some(crc) = frame.get(crc_end..crc_end + 2) else {
        return FrameCheck::BadCrc;
    };
    let extra = MavMessage::extra_crc(id);
    // The generated dialect answers 0 for an id it does not know.
    if extra == 0 && MavMessage::default_message_from_id(id).is_none() {
        return FrameCheck::UnknownMessage;
    }
    if mavlink::calculate_crc(&frame[1..crc_end], extra) == u16::from_le_bytes([crc[0], crc[1]]) {
        FrameCheck::Valid
    } else {
        FrameCheck::BadCrc
    }
}

/// Parses one raw MAVLink 1 or 2 frame (signed frames included; the signature is not checked
/// here, the link did that on receipt).
pub fn parse_frame(frame: &[u8]) -> Result<(MavHeader, MavMessage), TelemetryError> {
    let mut reader = MavlinkReader::with_capacity(0, frame);
    reader
        .read_any_message::<MavMessage>()
        .map_err(|e| TelemetryError::Frame {
            len: frame.len(),
            reason: e.to_string(),
        })
}

/// Serialises a message as one MAVLink 2 frame (unsigned), as it would go over the link.
pub fn frame_bytes(header: &MavHeader, message: &MavMessage) -> Vec<u8> {
    let mut raw = mavlink::MAVLinkV2MessageRaw::new();
    raw.serialize_message(*header, message);
    raw.raw_bytes().to_vec()
}

/// Serialises a message in the given protocol version (MAVLink 1 drops extension fields and
/// message ids above 255: those give None).
pub fn frame_bytes_versioned(
    header: &MavHeader,
    message: &MavMessage,
    version: MavlinkVersion,
) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    mavlink::write_versioned_msg(&mut out, version, *header, message)
        .ok()
        .map(|_| out)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::link::mav::{self, MavMessage};

    use crate::link::testing::autopilot_header as vehicle;

    #[test]
    fn check_frame_passes_whole_frames_fails_a_flipped_byte_and_knows_no_foreign_id() {
        let message = MavMessage::HEARTBEAT(mav::HEARTBEAT_DATA::default());
        let v2 = frame_bytes(&vehicle(), &message);
        assert_eq!(check_frame(&v2), FrameCheck::Valid);
        let v1 = frame_bytes_versioned(&vehicle(), &message, MavlinkVersion::V1).expect("v1");
        assert_eq!(check_frame(&v1), FrameCheck::Valid);
        for frame in [&v2, &v1] {
            for k in 1..frame.len() {
                let mut flipped = frame.clone();
                flipped[k] ^= 0x10;
                assert_ne!(check_frame(&flipped), FrameCheck::Valid, "byte {k}");
            }
        }
        // A message id no dialect here defines (0xABCDEF): its checksum cannot be judged.
        let mut foreign = v2.clone();
        foreign[7..10].copy_from_slice(&[0xEF, 0xCD, 0xAB]);
        assert_eq!(check_frame(&foreign), FrameCheck::UnknownMessage);
        // Too short to hold its own checksum: never a panic.
        assert_eq!(check_frame(&v2[..5]), FrameCheck::BadCrc);
        assert_eq!(check_frame(&[]), FrameCheck::BadCrc);
    }
}
