#!/usr/bin/env bash
# Emulated check of the blimp's install (docs/deploy.md, section 4) without a Pi.
#
# Builds an arm64 Debian Bookworm root with debootstrap, runs it through qemu-user-static, creates the
# venv exactly as the guide does (--system-site-packages, pip with constraints/pi-bookworm.txt) and
# imports the system's numpy stack together with OpenCV and Feelium in one interpreter: that is where a
# numpy 2 pulled in by pip would break the Debian-built camera modules.
#
# The Raspberry Pi archive (python3-picamera2, python3-simplejpeg) is added when it is reachable. Without
# it, Debian's python3-bottleneck stands in for simplejpeg: a C extension Debian compiled against its numpy
# 1.24, which must import beside the venv's numpy and OpenCV. A negative control then puts numpy 2 in front
# and expects that same module to fail, so the check can tell a good install from a bad one.
#
# Usage (root, network, ~2 GB free, 10-30 min on 2 cores):
#   sudo tools/pi-emulated-check.sh [WORKDIR]          # WORKDIR defaults to /var/tmp/feelium-pi-root
# Needs: debootstrap, qemu-user-static, binfmt-support (apt install debootstrap qemu-user-static binfmt-support).
# Behind a TLS-intercepting proxy, the host's PIP_CERT (a CA bundle) is copied into the root for pip;
# nothing else of the host's pip settings goes in (commands in the root run with a clean environment).
# Exit status: 0 all imports work, 1 an import failed, 2 the root could not be built.
set -euo pipefail

SRC=$(cd "$(dirname "$0")/.." && pwd)
ROOT=${1:-/var/tmp/feelium-pi-root}
DEBIAN_MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
RPI_ARCHIVE=${RPI_ARCHIVE:-http://archive.raspberrypi.com/debian}
PACKAGES=python3,python3-venv,python3-pip,python3-numpy,ca-certificates

step() { printf '\n== %s\n' "$*" >&2; }
die() { printf 'pi-emulated-check: %s\n' "$*" >&2; exit 2; }

[ "$(id -u)" = 0 ] || die "run as root (debootstrap and chroot need it)"
for tool in debootstrap qemu-aarch64-static update-binfmts; do
  command -v "$tool" >/dev/null || die "$tool is missing: apt install debootstrap qemu-user-static binfmt-support"
done

step "binfmt: arm64 binaries run through qemu"
if [ ! -e /proc/sys/fs/binfmt_misc/register ]; then
  mount -t binfmt_misc binfmt_misc /proc/sys/fs/binfmt_misc || die "cannot mount binfmt_misc (unprivileged container?)"
fi
update-binfmts --enable qemu-aarch64 || die "cannot register qemu-aarch64 with binfmt_misc"

cleanup() {
  for m in proc dev/pts dev sys; do umount "$ROOT/$m" 2>/dev/null || true; done
}
trap cleanup EXIT

if [ ! -x "$ROOT/usr/bin/python3" ]; then
  step "debootstrap arm64 bookworm into $ROOT (first stage)"
  rm -rf "$ROOT"
  debootstrap --arch=arm64 --variant=minbase --foreign --include="$PACKAGES" bookworm "$ROOT" "$DEBIAN_MIRROR" \
    || die "debootstrap (first stage) failed"
  # The binfmt entry names an interpreter path without the F flag, so it must exist inside the root.
  interp=$(sed -n 's/^interpreter //p' /proc/sys/fs/binfmt_misc/qemu-aarch64)
  mkdir -p "$ROOT$(dirname "$interp")" "$ROOT/usr/bin"
  cp "$(readlink -f "$interp")" "$ROOT$interp"
  cp /usr/bin/qemu-aarch64-static "$ROOT/usr/bin/"
  step "debootstrap second stage (under qemu)"
  chroot "$ROOT" /debootstrap/debootstrap --second-stage || die "debootstrap (second stage) failed"
fi

# Commands in the root see a Pi's environment, not the host's (no PIP_* settings, no host paths).
in_root() { chroot "$ROOT" env -i PATH=/usr/local/bin:/usr/bin:/bin HOME=/root LANG=C.UTF-8 ${ROOT_PIP_CERT:+PIP_CERT=$ROOT_PIP_CERT} "$@"; }
ROOT_PIP_CERT=
if [ -n "${PIP_CERT:-}" ] && [ -f "$PIP_CERT" ]; then
  cp "$PIP_CERT" "$ROOT/etc/ssl/certs/host-ca-bundle.crt"
  ROOT_PIP_CERT=/etc/ssl/certs/host-ca-bundle.crt
fi

mount -t proc proc "$ROOT/proc"
mount --bind /dev "$ROOT/dev"
mount --bind /dev/pts "$ROOT/dev/pts"
mount --bind /sys "$ROOT/sys"
cp /etc/resolv.conf "$ROOT/etc/resolv.conf"

camera_stack="numpy"
step "Raspberry Pi archive: $RPI_ARCHIVE"
if curl -fsS --max-time 20 "$RPI_ARCHIVE/dists/bookworm/InRelease" -o /dev/null 2>/dev/null; then
  curl -fsS "$RPI_ARCHIVE/raspberrypi.gpg.key" | gpg --dearmor >"$ROOT/usr/share/keyrings/raspberrypi.gpg"
  echo "deb [signed-by=/usr/share/keyrings/raspberrypi.gpg] $RPI_ARCHIVE bookworm main" >"$ROOT/etc/apt/sources.list.d/raspi.list"
  in_root apt-get update -qq
  in_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    python3-picamera2 python3-simplejpeg
  camera_stack="numpy, simplejpeg, picamera2"
else
  echo "unreachable: Debian's python3-bottleneck (built against numpy 1.24) stands in for simplejpeg and picamera2" >&2
  in_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends python3-bottleneck
  camera_stack="numpy, bottleneck"
fi

step "the guide's section 4: venv with system site packages, pip with the constraints"
rm -rf "$ROOT/opt/feelium"
mkdir -p "$ROOT/opt/feelium/src"
git -C "$SRC" ls-files -z | (cd "$SRC" && tar --null -T - -cf -) | tar -xf - -C "$ROOT/opt/feelium/src"
in_root python3 -m venv --system-site-packages /opt/feelium/venv
in_root /opt/feelium/venv/bin/pip install -q -c /opt/feelium/src/constraints/pi-bookworm.txt --upgrade pip
in_root /opt/feelium/venv/bin/pip install -q -c /opt/feelium/src/constraints/pi-bookworm.txt /opt/feelium/src

step "imports together: $camera_stack, cv2, feelium"
check=$(cat <<EOF
import importlib, platform, sys
names = [n.strip() for n in "$camera_stack".split(",")] + ["cv2", "feelium", "feelium.daemon.runner"]
for name in names:
    module = importlib.import_module(name)
    print(f"{name:24} {getattr(module, '__version__', '')} {getattr(module, '__file__', '')}")
import numpy, cv2
assert numpy.__version__.split(".")[0] == "1", numpy.__version__
print("ok:", platform.machine(), "Python", platform.python_version(), "numpy", numpy.__version__, "cv2", cv2.__version__)
EOF
)
if ! in_root /opt/feelium/venv/bin/python -c "$check"; then
  echo "pi-emulated-check: an import failed (above)" >&2
  exit 1
fi
echo "pi-emulated-check: all imports work ($camera_stack, cv2, feelium)"

step "negative control: the same imports with numpy 2 in front (what an unconstrained install gives)"
compiled=$(echo "$camera_stack" | tr -d ' ' | tr ',' '\n' | grep -v '^numpy$' | head -1)
in_root /opt/feelium/venv/bin/pip install -q --target /tmp/numpy2 "numpy>=2"
if in_root env PYTHONPATH=/tmp/numpy2 /opt/feelium/venv/bin/python -c "import numpy, $compiled; print(numpy.__version__)"; then
  echo "pi-emulated-check: $compiled imported beside numpy 2: this check cannot tell a bad install" >&2
  exit 1
fi
echo "pi-emulated-check: as expected, $compiled fails beside numpy 2 and works with the constrained install"
