#!/usr/bin/env bash
# The dashboard in a real browser: starts `emplan serve` on the built-in mock with a temporary
# missions folder holding MISSION and a temporary log directory, then drives the page in
# headless Chromium (Debian's, through playwright-core; sitl/dashboard/check.mjs): upload and
# start through the page's own controls with the token typed into it and the pack named in its
# Pack field, the live leg table filled leg by leg, the flight's report with every leg, and the
# Packs page listing the pack with its flight and a capacity (the flight written to the ledger,
# LOGDIR/ledger.sqlite). Then a second service, `--guard rtl` with the
# mock flying a heavier vehicle with a smaller pack (`--mock-vehicle`), and a mission it cannot
# finish with the reserve: the live view's guard panel shows the warning and the return. Screenshots go to OUT (default
# target/dashboard). Installs what it needs (chromium, fonts, npm ci); stops what it started.
#
# usage: sitl/dashboard-check.sh [EMPLAN] [MISSION] [OUT]
set -euo pipefail
cd "$(dirname "$0")/.."
emplan=${1:-target/debug/emplan}
mission=${2:-missions/paper-sample-8wp.toml}
out=${3:-target/dashboard}

apt_updated=
apt_install() {
    [ -n "$apt_updated" ] || { apt-get update -qq; apt_updated=1; }
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}
[ -x /usr/bin/chromium ] || apt_install chromium
# Chromium draws text with fontconfig's fonts: without any, every label is blank.
fc-list 2>/dev/null | grep -qi dejavu || apt_install fonts-dejavu-core
command -v node >/dev/null && command -v npm >/dev/null || apt_install nodejs npm
(cd sitl/dashboard && npm ci --no-audit --no-fund --loglevel=error)

work=$(mktemp -d -t emplan-dashboard.XXXXXX)
serve_pid=
cleanup() {
    if [ -n "$serve_pid" ] && kill -0 "$serve_pid" 2>/dev/null; then
        kill -TERM "$serve_pid"
        wait "$serve_pid" 2>/dev/null || true
    fi
    rm -rf "$work"
}
trap cleanup EXIT
mkdir -p "$work/missions" "$work/flights" "$out"
cp "$mission" "$work/missions/"
# A mission one battery cannot fly: listed infeasible, its sorties shown.
cp missions/long-inspection.toml "$work/missions/"
# A file that does not read as a mission (a NaN coordinate): the page lists it with its line.
printf 'name = "broken"\n[origin]\nlat_deg = 38.5\nlon_deg = -121.7\nhome_alt_amsl_m = 16.0\nheight_above_home_m = 30.0\n\n[[waypoints]]\nname = "A"\nx_m = 1.0\ny_m = nan\nz_m = 5.0\n' \
    >"$work/missions/broken.toml"
serve() { # LOGDIR ARGS...: starts `emplan serve` logging into LOGDIR, sets serve_pid and url
    local dir=$1
    shift
    "$emplan" serve --log-dir "$dir" --http 127.0.0.1:0 "$@" >"$dir.url" 2>"$dir.log" &
    serve_pid=$!
    for _ in $(seq 1 300); do
        [ -s "$dir.url" ] && break
        kill -0 "$serve_pid" 2>/dev/null || { cat "$dir.log" >&2; echo "emplan serve exited" >&2; exit 1; }
        sleep 0.1
    done
    url=$(head -n 1 "$dir.url")
    [ -n "$url" ] || { cat "$dir.log" >&2; echo "emplan serve printed no URL" >&2; exit 1; }
}
stop_serve() {
    kill -TERM "$serve_pid"
    wait "$serve_pid" 2>/dev/null || true
    serve_pid=
}
serve "$work/flights" --missions "$work/missions"
echo "dashboard-check: $url (missions $work/missions, flights $work/flights)"
status=0
node sitl/dashboard/check.mjs --url "$url" --token-file "$work/flights/token" \
    --mission "$(basename "$mission")" --broken broken.toml \
    --infeasible long-inspection.toml --pack P-check --out "$out" || status=$?
if [ "$status" -ne 0 ]; then
    echo "== emplan serve's log" >&2
    tail -n 40 "$work/flights.log" >&2
    exit "$status"
fi
stop_serve

# The energy guard: the mock flies the shipped S1000 25% heavier with a 15% smaller pack (8.5 Ah,
# 170 Wh usable), the plans the shipped vehicle; the long survey with a minute's hover at each
# waypoint lands below the reserve unless the guard (rtl) sends the vehicle home.
mkdir -p "$work/guarded" "$work/heavier" "$work/guarded-flights"
sed 's/^default_hover_s = 5.0$/default_hover_s = 60.0/' missions/long-survey.toml \
    >"$work/guarded/long-survey-hover.toml"
grep -q '^default_hover_s = 60.0$' "$work/guarded/long-survey-hover.toml" \
    || { echo "missions/long-survey.toml: no default_hover_s = 5.0 to change" >&2; exit 1; }
awk '
    $1 == "mass_kg" && $3 == "5.8069" { print "mass_kg = 7.258625"; n++; next }
    $1 == "capacity_ah" && $3 == "10.0" { print "capacity_ah = 8.5"; n++; next }
    $1 == "usable_energy_wh" && $3 == "200.0" { print "usable_energy_wh = 170"; n++; next }
    { print }
    END { if (n != 3) { print "models/s1000/vehicle.toml: " n " of 3 values changed" > "/dev/stderr"; exit 1 } }
' models/s1000/vehicle.toml >"$work/heavier/vehicle.toml"
serve "$work/guarded-flights" --missions "$work/guarded" --guard rtl \
    --mock-vehicle "$work/heavier" --speedup 50
echo "dashboard-check: guarded $url (flights $work/guarded-flights)"
node sitl/dashboard/check.mjs --url "$url" --token-file "$work/guarded-flights/token" \
    --mission long-survey-hover.toml --guard yes --out "$out" || status=$?
if [ "$status" -ne 0 ]; then
    echo "== emplan serve's log" >&2
    tail -n 40 "$work/guarded-flights.log" >&2
fi
exit "$status"
