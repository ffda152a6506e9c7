#!/usr/bin/env bash
# Rebuild the report's vendored three.js (bench/report/vendor/three/) from the npm registry.
#
# The report's 3D view opens from disk (file://), where Chromium loads neither ES modules
# nor fetch()ed files, so three.js, its GLTFLoader and its OrbitControls are bundled into
# one classic script that puts them on `window.THREE`. Both versions are pinned; npm checks
# each package against the registry's integrity hash. Needs Node and npm.
#
#   bash scripts/vendor_three.sh           rebuild three.min.js, LICENSE and VERSION
#   bash scripts/vendor_three.sh --check   rebuild in a temporary folder and fail unless
#                                          the bundle is byte for byte the committed one
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in
    ""|--check) ;;
    *) echo "vendor_three: unknown argument '$1' (give nothing to rebuild, or --check)" >&2
       exit 2 ;;
esac

THREE_VERSION=0.187.0
ESBUILD_VERSION=0.28.2
DEST=bench/report/vendor/three

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
npm install --no-save --no-audit --no-fund --ignore-scripts --loglevel=error \
    "three@$THREE_VERSION" "esbuild@$ESBUILD_VERSION" >/dev/null
# The entry: all of three, plus the two add-ons the viewer uses, on one global.
cat > entry.js <<'EOF'
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
window.THREE = Object.assign({}, THREE, { GLTFLoader, OrbitControls });
EOF
./node_modules/.bin/esbuild entry.js --bundle --minify --format=iife --legal-comments=inline \
    --log-level=warning --outfile=three.min.js
cd - >/dev/null

sha=$(sha256sum "$work/three.min.js" | cut -d' ' -f1)
if [ "${1:-}" = "--check" ]; then
    committed=$(sed -n 's/^sha256 //p' "$DEST/VERSION")
    on_disk=$(sha256sum "$DEST/three.min.js" | cut -d' ' -f1)
    if [ "$sha" != "$committed" ] || [ "$on_disk" != "$committed" ]; then
        echo "vendor_three: the rebuilt bundle's sha256 $sha, the committed file's $on_disk" \
             "and VERSION's $committed differ" >&2
        exit 1
    fi
    if ! cmp -s "$work/node_modules/three/LICENSE" "$DEST/LICENSE"; then
        echo "vendor_three: $DEST/LICENSE is not three $THREE_VERSION's" >&2
        exit 1
    fi
    echo "vendor_three: $DEST/three.min.js and LICENSE rebuild byte for byte ($sha)"
    exit 0
fi
mkdir -p "$DEST"
cp "$work/three.min.js" "$DEST/three.min.js"
cp "$work/node_modules/three/LICENSE" "$DEST/LICENSE"
cat > "$DEST/VERSION" <<EOF
three $THREE_VERSION
esbuild $ESBUILD_VERSION
sha256 $sha
bytes $(stat -c %s "$DEST/three.min.js")
built by scripts/vendor_three.sh: three, GLTFLoader and OrbitControls as one classic (IIFE) script on window.THREE
EOF
echo "vendor_three: wrote $DEST/three.min.js ($(stat -c %s "$DEST/three.min.js") bytes, sha256 $sha)"
