#!/usr/bin/env bash
# Calibration that carries to the next flight, on physics we did not write: ArduCopter SITL
# (sitl/ardupilot-fly.sh) flies the two paper samples (missions/paper-sample-8wp.toml and
# paper-sample-3wp.toml); `emplan calibrate --from-logs` fits the vehicle to those two flights and
# writes a calibrated vehicle directory; ArduCopter SITL then flies a held-out generated mission
# (`emplan generate --waypoints 6 --xy 40 --z 20 --seed 5`: no holds, so ArduCopter flies its
# waypoints through, blending the corners; HELD_OUT_HOVER_S=S holds S s at each instead), and
# `emplan report
# HELD_OUT --vehicle CALIBRATED --json` re-prices that flight with the calibrated vehicle. Fails
# unless every leg is within LEGS_WITHIN % (default 10) and the mission within MISSION_WITHIN %
# (default 3) of the calibrated vehicle's prices (sitl/check_repriced.py), and prints the same
# flight priced with the uncalibrated S1000 beside it (how far off that was).
#
# The calibration reads the flight directories (plan.json, report.json, samples.csv), not the
# DataFlash .bin files: the held-out flight's report is measured from its .tlog, so the fit and
# the check measure energy the same way, and samples.csv lets the fit refit the pack too.
#
# The profile the legs are priced with: the one each flight was flown with (its plan.json says;
# `fly` picks ArduCopter's own, `ardupilot`), which `calibrate --from-logs` and `report` take
# by themselves, as a field team runs them: no --profile, no --tables (calibrate builds that
# profile's table only; the calibrated directory's vehicle.toml carries the fit for the others,
# `emplan table build`). PROFILE=P passes --profile P to both instead.
# The airframe's mass is given, as a field team weighs theirs (`calibrate --mass-kg`): MASS_KG,
# default the SITL frame's own (s1000.json "mass", 6.971 kg); MASS_KG= (empty) fits it instead.
# Usage: sitl/ardupilot-calibrate.sh [EMPLAN_BINARY] [WORK_DIR]; SITL_INSTANCE as ardupilot-fly.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
work=${2:-$(mktemp -d -t emplan-ardupilot-calibrate.XXXXXX)}
mkdir -p "$work"
profile_args=()
if [ -n "${PROFILE:-}" ]; then
  profile_args=(--profile "$PROFILE")
  echo "== pricing with the $PROFILE profile (PROFILE)"
else
  echo "== pricing with the profile the flights were flown with"
fi
shared=${SHARED_SITL:-../shared/sitl}
[ -d "$shared" ] || shared=/work/shared/sitl
mass=${MASS_KG-$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["mass"])' \
  "$shared/ardupilot/s1000.json")}
mass_args=()
if [ -n "$mass" ]; then
  mass_args=(--mass-kg "$mass")
  echo "== the airframe weighs $mass kg (given, not fitted)"
fi
# The held-out mission: emplan generate's default home is ArduCopter SITL's.
"$emplan" generate --waypoints 6 --xy 40 --z 20 --seed 5 --hover-s "${HELD_OUT_HOVER_S:-0}" --name held-out-6wp \
  --force "$work/held-out-6wp.toml" >/dev/null
fly() {
  local mission=$1 name
  name=$(basename "$mission" .toml)
  echo "== ArduCopter SITL flies $name" >&2
  mkdir -p "$work/$name"
  bash sitl/ardupilot-fly.sh "$emplan" "$mission" "$work/$name" >&2
  python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["log_dir"])' "$work/$name/fly.json"
}
fitted=()
for mission in missions/paper-sample-8wp.toml missions/paper-sample-3wp.toml; do
  fitted+=("$(fly "$mission")")
done
echo "== emplan calibrate --from-logs ${fitted[*]} ${mass_args[*]}"
"$emplan" calibrate --from-logs "${fitted[@]}" "${mass_args[@]}" ${profile_args[@]+"${profile_args[@]}"} \
  --out "$work/calibrated" --force --json >"$work/calibrate.json"
python3 - "$work/calibrate.json" <<'PY'
import json, sys
doc = json.load(open(sys.argv[1]))
print(f"fitted with the {doc['profile']} profile; tables written: "
      + ", ".join(w for w in doc["written"] if w.endswith(".table")))
for t in doc.get("tables_left_out", []):
    print(f"  table {t['profile']} left out: {t['reason']}")
for name in ("before", "after", "held_out"):
    s = doc.get(name)
    if s:
        print(f"legs {name:<9} rms {s['rms_pct']:6.1f}%  mean {s['mean_pct']:+6.1f}%  worst {s['worst_pct']:6.1f}%")
for f in doc["changed"]:
    bound = f"  AT ITS {f['at_bound'].upper()} BOUND" if f.get("at_bound") else ""
    print(f"  {f['key']}: {f['before']:.4g} -> {f['value']:.4g} (bounds {f['low']:.4g}-{f['high']:.4g}){bound}")
PY
held_out=$(fly "$work/held-out-6wp.toml")
echo "== emplan report $held_out --vehicle $work/calibrated${profile_args[*]+ ${profile_args[*]}} --json"
"$emplan" report "$held_out" --vehicle "$work/calibrated" ${profile_args[@]+"${profile_args[@]}"} --json \
  >"$work/held-out-calibrated.json"
"$emplan" report "$held_out" --vehicle models/s1000 ${profile_args[@]+"${profile_args[@]}"} --json \
  >"$work/held-out-uncalibrated.json"
python3 sitl/check_repriced.py "$work/held-out-calibrated.json" \
  --uncalibrated "$work/held-out-uncalibrated.json" --vehicle-dir "$work/calibrated" \
  --legs-within "${LEGS_WITHIN:-10}" --mission-within "${MISSION_WITHIN:-3}"
