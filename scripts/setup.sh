#!/usr/bin/env bash
# Set up everything on a fresh Debian 12 machine with Python 3.11, then run the main job.
# Installs the test tools and Dask (the dask extra: bench run --executor dask, its tests).
#   bash scripts/setup.sh            install + run the main job on built-in models
#   bash scripts/setup.sh --no-run   install and compile the kernels only (what CI uses)
set -euo pipefail
cd "$(dirname "$0")/.."

# Headless OpenGL through EGL on Mesa's llvmpipe (no GPU, no display needed), plus venv,
# plus Node.js and npm, which run meshoptimizer and gltfpack (the meshopt* and gltfpack rows).
PKGS="libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgbm1 python3-venv"
# Debian's nodejs and npm, unless node and npm are there already: NodeSource's nodejs
# bundles npm, and Debian's npm package cannot be installed beside it.
command -v node >/dev/null && command -v npm >/dev/null || PKGS="$PKGS nodejs npm"
missing=$(dpkg-query -W -f='${db:Status-Abbrev} ${Package}\n' $PKGS 2>/dev/null | awk '$1!="ii"{print $2}'; \
          for p in $PKGS; do dpkg-query -W "$p" >/dev/null 2>&1 || echo "$p"; done)
if [ -n "$(echo $missing)" ]; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $PKGS
fi

PYTHON=${PYTHON:-$(command -v python3.11 || command -v python3)}
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
# Exact versions (constraints.txt, from pip freeze): the same numbers from the same
# command on any day; regenerate it with the baselines when upgrading on purpose.
.venv/bin/python -m pip install -q -c constraints.txt -e '.[test,dask]'
# meshoptimizer and gltfpack 1.3.0 from the npm registry, exactly as the lockfile pins them
# (integrity hashes checked); without them those rows are listed as unavailable.
npm ci --prefix methods/meshopt_node --no-audit --no-fund --loglevel=error \
    || echo "setup: npm ci failed; the meshopt* and gltfpack rows stay unavailable" >&2
if [ "${1:-}" != "--no-run" ]; then
    # The main job: every available method on the bunny and the textured torus at 2 % and
    # 1 % of their faces, evaluated under the protocol; report in reports/quickstart/.
    # On a fresh install its jobs compile the numba kernels (cached on disk) as they go:
    # each family once, in one process, while the other runs jobs that need none of it.
    .venv/bin/bench run --models bunny,torus --out reports/quickstart
    echo "report: $(pwd)/reports/quickstart/index.html"
else
    # Compile the numba kernels once (cached on disk), so no run or test pays for it.
    .venv/bin/bench warmup
fi
