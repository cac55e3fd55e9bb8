//! A flight record as the store's rows: its row of `flights` (the columns for querying and the
//! record as JSON), its rows of `parts`, and the check that it is a record the ledger can keep.

use super::{Conn, Param};
use crate::ledger::{FlightRecord, LedgerError, Outcome};

/// The flight's row of `flights`, in the order of `FLIGHT_COLUMNS` (the store's).
pub(super) fn flight_row(record: &FlightRecord, json: &str) -> Vec<Param> {
    let text = |v: &Option<String>| Param::Text(v.clone());
    vec![
        Param::Text(Some(record.id.clone())),
        text(&record.vehicle),
        text(&record.pack),
        Param::Text(Some(record.mission.clone())),
        text(&record.profile),
        text(&record.autopilot),
        text(&record.started_at),
        Param::Text(Some(outcome_name(record.outcome).to_string())),
        Param::Real(Some(record.duration_s)),
        Param::Real(record.predicted_j),
        Param::Real(record.measured_j),
        Param::Real(record.charge_ah),
        Param::Text(Some(json.to_string())),
    ]
}

pub(super) fn insert_parts(conn: &mut dyn Conn, record: &FlightRecord) -> Result<(), String> {
    for (k, part) in record.parts.iter().enumerate() {
        conn.execute(
            "INSERT INTO parts (flight_id, idx, kind, name, predicted_j, measured_j, duration_s) \
             VALUES ($1, $2, $3, $4, $5, $6, $7)",
            &[
                Param::Text(Some(record.id.clone())),
                Param::Int(Some(i64::try_from(k).unwrap_or(i64::MAX))),
                Param::Text(Some(part.kind.clone())),
                Param::Text(Some(part.name.clone())),
                Param::Real(part.predicted_j),
                Param::Real(part.measured_j),
                Param::Real(part.duration_s),
            ],
        )?;
    }
    Ok(())
}

/// The outcome as the record's JSON names it.
fn outcome_name(outcome: Outcome) -> &'static str {
    match outcome {
        Outcome::Completed => "completed",
        Outcome::Returned => "returned",
        Outcome::Incomplete => "incomplete",
        Outcome::CutOff => "cut_off",
    }
}

/// A record the ledger can keep: an id, and every number finite (JSON has no NaN: one would
/// come back as a null, or not at all).
pub(super) fn check_record(record: &FlightRecord) -> Result<(), LedgerError> {
    let refuse = |message: String| LedgerError::Flight {
        path: record.path.clone(),
        message,
    };
    if record.id.is_empty() {
        return Err(refuse("the record has no id".to_string()));
    }
    let mut numbers: Vec<(String, Option<f64>)> = vec![
        ("wind_m_s".into(), record.wind_m_s),
        ("wind_from_deg".into(), record.wind_from_deg),
        ("duration_s".into(), Some(record.duration_s)),
        ("predicted_j".into(), record.predicted_j),
        ("measured_j".into(), record.measured_j),
        ("charge_ah".into(), record.charge_ah),
    ];
    for (k, part) in record.parts.iter().enumerate() {
        numbers.push((format!("parts[{k}].predicted_j"), part.predicted_j));
        numbers.push((format!("parts[{k}].measured_j"), part.measured_j));
        numbers.push((format!("parts[{k}].duration_s"), part.duration_s));
    }
    if let Some(g) = &record.guard {
        numbers.push(("guard.correction".into(), Some(g.correction)));
        numbers.push(("guard.capacity_ratio".into(), Some(g.capacity_ratio)));
        numbers.push((
            "guard.state_of_charge_at_takeoff".into(),
            g.state_of_charge_at_takeoff,
        ));
    }
    if let Some(p) = &record.pack_fit {
        for (name, value) in [
            ("capacity_ah", p.capacity_ah),
            ("label_capacity_ah", p.label_capacity_ah),
            ("capacity_sd_ah", p.capacity_sd_ah),
            ("internal_resistance_ohm", p.internal_resistance_ohm),
            ("state_of_charge_at_takeoff", p.state_of_charge_at_takeoff),
            ("voltage_rms_v", p.voltage_rms_v),
        ] {
            numbers.push((format!("pack_fit.{name}"), Some(value)));
        }
    }
    match numbers
        .into_iter()
        .find(|(_, v)| v.is_some_and(|v| !v.is_finite()))
    {
        Some((field, Some(value))) => Err(refuse(format!(
            "record `{}`: {field} is {value}, which the ledger cannot keep",
            record.id
        ))),
        _ => Ok(()),
    }
}
