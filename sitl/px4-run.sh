#!/usr/bin/env bash
# Runs PX4 SITL (../shared/sitl/px4/run.sh) from a shadow directory. The shared copy's bin/px4-*
# commands are symlinks flattened into 3-byte files holding "px4", and ../shared is read-only, so
# PX4's startup script fails there ("px4-param: Permission denied"). The shadow directory
# (under $PX4_SHADOW, default $TMPDIR or /tmp) links bin/px4 and etc/ back to the shared build and
# makes every flattened px4-* file a real symlink to px4 again.
#
# Usage: sitl/px4-run.sh [extra px4 args]   (foreground; stop it with SIGTERM to its PID)
# Takes the same environment as ../shared/sitl/px4/run.sh: PX4_WORKDIR, PX4_INSTANCE,
# PX4_SYS_AUTOSTART, PX4_HOME_LAT/LON/ALT, PX4_PARAM_<NAME>=<value>, PX4_SIM_SPEED_FACTOR; and
# PX4_SITL_DIR (default ../shared/sitl/px4 beside this checkout, else /work/shared/sitl/px4).
# PX4 sends its GCS stream to UDP 127.0.0.1:14550: connect with udpin:127.0.0.1:14550.
# One PX4 instance per machine at a time (every instance sends to 14550).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
src=${PX4_SITL_DIR:-}
if [ -z "$src" ]; then
  for candidate in "$here/../../shared/sitl/px4" "/work/shared/sitl/px4"; do
    if [ -x "$candidate/run.sh" ]; then src=$(cd "$candidate" && pwd); break; fi
  done
fi
if [ -z "$src" ] || [ ! -x "$src/bin/px4" ]; then
  echo "px4-run.sh: no PX4 SITL build found (set PX4_SITL_DIR to the directory holding run.sh and bin/px4)" >&2
  exit 2
fi
src=$(cd "$src" && pwd)
shadow=${PX4_SHADOW:-$(mktemp -d "${TMPDIR:-/tmp}/px4shadow.XXXXXX")}
mkdir -p "$shadow/bin"
ln -sfn "$src/etc" "$shadow/etc"
cp "$src/run.sh" "$shadow/run.sh"
ln -sfn "$src/bin/px4" "$shadow/bin/px4"
for f in "$src"/bin/px4-*; do
  b=$(basename "$f")
  if [ "$(head -c 8 "$f")" = "px4" ]; then
    ln -sfn px4 "$shadow/bin/$b"
  else
    cp "$f" "$shadow/bin/$b"
  fi
done
echo "px4 shadow directory: $shadow" >&2
exec "$shadow/run.sh" "$@"
