#!/usr/bin/env bash
# The round trip with Blender, headless: Blender builds a room and exports it as glTF
# (tests/data/blender/make_room.py), sirad solves it and writes the .glb of the solution, and
# Blender imports that and checks every object came back with its colours
# (deploy/blender/check_import.py), and the .ply with its vertex colours. Skipped (exit 0, says so) where Blender is not installed;
# CI does not need it. Usage: deploy/blender-roundtrip.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
if ! command -v blender >/dev/null; then
  echo "blender-roundtrip: Blender is not installed (apt-get install blender): skipped"
  exit 0
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
blender -b --factory-startup --python tests/data/blender/make_room.py -- "$work" > "$work/export.log" 2>&1 ||
  { cat "$work/export.log"; exit 1; }
"$build/sirad" render "$work/room.glb" --patches 3000 --bundles 400 --out "$work/solved" -q
blender -b --factory-startup --python deploy/blender/check_import.py -- "$work/solved.glb" Room Lamp Block 2>&1 |
  grep -E "vertices|ROUND TRIP" | tee "$work/import.log"
grep -q "ROUND TRIP OK" "$work/import.log"
blender -b --factory-startup --python deploy/blender/check_import.py -- "$work/solved.ply" 2>&1 |
  grep -E "vertices|ROUND TRIP" | tee "$work/import-ply.log"
grep -q "ROUND TRIP OK" "$work/import-ply.log"
