#!/usr/bin/env sh
# The project on the blimp's library versions, checked on this machine. Development and CI run numpy 2 and
# OpenCV 5; the Pi runs numpy 1.x and OpenCV 4.11 (constraints/pi-bookworm.txt, docs/deploy.md section 4), so
# code that needs a newer numpy or OpenCV would pass every test here and fail on the blimp. This installs the
# project with the Pi's constraints into .venv-pi (x86_64 wheels of the same versions), imports every module,
# and runs what a user runs first: the simulated daemon, a recording, its replay and an evaluation.
# Exit 0 when all of it works. Run by .ci/run; safe to run again.
set -eu
cd "$(dirname "$0")/.."
root=$(pwd)
# The blimp's Python is Bookworm's 3.11, and numpy 1.x has no wheels for the newest Pythons: check with 3.11.
interpreter=""
for candidate in python3.11 python3; do
  if command -v "$candidate" >/dev/null 2>&1 && "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
    interpreter=$candidate
    break
  fi
done
if [ -z "$interpreter" ]; then
  echo "pi versions: skipped: no Python 3.11 here (the Pi's version; numpy 1.x may not install on another)" >&2
  exit 0
fi
[ -x .venv-pi/bin/python ] || "$interpreter" -m venv .venv-pi
py="$root/.venv-pi/bin/python"
"$py" -m pip install -q -c constraints/pi-bookworm.txt "$root"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"  # the installed package, not the checkout's sources
"$py" - <<'PY'
import importlib, pkgutil
import cv2, numpy
import feelium
assert numpy.__version__.startswith("1."), numpy.__version__
names = [m.name for m in pkgutil.walk_packages(feelium.__path__, "feelium.") if not m.name.endswith("__main__")]
for name in names:
    importlib.import_module(name)
print(f"pi versions: numpy {numpy.__version__}, OpenCV {cv2.__version__}: {len(names)} modules import")
PY
printf '[http]\nport = 0\n[daemon]\nstatus_interval_s = 1\n' > feelium.toml
"$py" -m feelium run --config feelium.toml > run.log 2>&1 &
daemon=$!
waited=0
until grep -q "feelium running" run.log; do  # up and every service started (or failed, which the log says)
  sleep 1
  waited=$((waited + 1))
  [ "$waited" -lt 90 ] && kill -0 "$daemon" 2>/dev/null || { cat run.log; echo "pi versions: the daemon never ran" >&2; exit 1; }
done
sleep 5  # a few seconds of every service at work
kill -INT "$daemon"
wait "$daemon" || { cat run.log; echo "pi versions: feelium run failed" >&2; exit 1; }
if grep -q "Traceback" run.log; then cat run.log; echo "pi versions: a traceback in the daemon's log" >&2; exit 1; fi
"$py" -m feelium record --sim --seconds 3 --out take > /dev/null
"$py" -m feelium replay take > /dev/null
"$py" -m feelium eval "$root/recordings" --json eval.json --figure eval.png > /dev/null
echo "pi versions: feelium run, record, replay and eval work"
