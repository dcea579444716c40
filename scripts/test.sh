#!/usr/bin/env bash
# Install what the tests need (system GL/EGL libraries, Python packages) and run the test suite.
# Extra arguments go to pytest, e.g. `scripts/test.sh -m slow` or `scripts/test.sh tests/physics`.
set -euo pipefail
cd "$(dirname "$0")/.."

# system libraries for headless rendering (EGL, Mesa), Qt offscreen, and a virtual X server for the
# real OpenGL window test; skipped when present
need=()
for pkg in libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1 libgl1 fontconfig fonts-dejavu-core libxkbcommon0 \
           libdbus-1-3 libglib2.0-0 xvfb xauth libxcb-icccm4 libxcb-keysyms1 libxcb-cursor0 libxcb-image0 \
           libxcb-render-util0 libxcb-shape0 libxcb-xkb1 libxkbcommon-x11-0 libxcb-randr0; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
  else
    echo "scripts/test.sh: missing system packages (install them with apt): ${need[*]}" >&2
  fi
fi

python -m pip install -q -e ".[test]"
export QT_QPA_PLATFORM=offscreen
exec python -m pytest "$@"
