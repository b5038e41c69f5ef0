#!/usr/bin/env sh
# Set up a fresh machine for Feelium in one step: the system packages it needs (Debian and Ubuntu, with
# sudo unless root), a virtual environment in .venv (Debian's Python refuses pip outside one, PEP 668,
# and may lack pip and venv altogether) and the project installed in it, editable.
#   tools/setup.sh        the daemon's dependencies
#   tools/setup.sh test   and the tests' (pytest, hypothesis, Playwright; ffmpeg, Chromium, openssl)
# Safe to run again: what is there already is kept. The Pi's own install is docs/deploy.md.
set -eu
cd "$(dirname "$0")/.."
want="${1:-run}"
case "$want" in run|test) ;; *) echo "usage: tools/setup.sh [run|test]" >&2; exit 2 ;; esac

missing=""
python3 -c 'import venv, ensurepip' 2>/dev/null || missing="python3-venv"
if [ "$want" = test ]; then
  for package in $(cat .ci/apt-packages.txt); do
    command -v "$package" >/dev/null 2>&1 || missing="$missing $package"
  done
fi
if [ -n "$missing" ]; then
  if command -v apt-get >/dev/null 2>&1; then
    as_root=""
    [ "$(id -u)" = 0 ] || as_root="sudo"
    echo "tools/setup.sh: installing system packages:$missing" >&2
    $as_root apt-get update -qq
    # shellcheck disable=SC2086  # one word per package
    DEBIAN_FRONTEND=noninteractive $as_root apt-get install -y -qq --no-install-recommends $missing >/dev/null
  else
    echo "tools/setup.sh: please install:$missing (no apt-get here); going on without them" >&2
  fi
fi

[ -x .venv/bin/python ] || python3 -m venv .venv
if [ "$want" = test ]; then
  .venv/bin/python -m pip install -q -e '.[test]'
else
  .venv/bin/python -m pip install -q -e .
fi
