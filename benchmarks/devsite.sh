#!/usr/bin/env bash
# Build .devsite/site.tgz: the packages a lent GPU machine lacks, for its python3 (3.12, torch with
# CUDA), so that benchmarks/device_check.sh runs there with nothing to download. Run here, in a
# checkout whose .venv has `pip install -e '.[dev]'` done (its pure-Python packages are copied).
#
#   bash benchmarks/devsite.sh [PYTHON_VERSION]    (default 3.12)
#
# What goes in (~15 MB packed, under the device tool's 64 MiB with the working tree; the tracked
# docs/policies and docs/figures are best left out of a call, see CONTRIBUTING.md): the cp312
# wheels of torchrl, tensordict, mujoco, dm-tree and orjson; dm_control without its locomotion
# assets, dog model and tests; gymnasium_robotics's Shadow Hand MJCF, meshes and textures only;
# hydra, omegaconf, antlr4, dm_env, hoptorch, pyvers, importlib_metadata (pure Python). No
# OpenGL: the check runs with MUJOCO_GL=disable.
set -euo pipefail
cd "$(dirname "$0")/.."
PYV="${1:-3.12}"
SP=".venv/lib/python3.11/site-packages"
[ -d "$SP/dm_control" ] || { echo "devsite.sh: no $SP/dm_control (run pip install -e '.[dev]' first)" >&2; exit 2; }
grep -qx "/.devsite/" .git/info/exclude 2>/dev/null || echo "/.devsite/" >>.git/info/exclude
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
wheels="$tmp/wheels" site="$tmp/site"
mkdir -p "$wheels" "$site"
python3 -m pip download -q --no-deps --only-binary=:all: --python-version "$PYV" \
  --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
  --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 -d "$wheels" \
  torchrl==0.14.1 tensordict==0.14.3 mujoco==3.17.0 dm-control==1.0.50 dm-tree orjson
for w in "$wheels"/*.whl; do python3 -m zipfile -e "$w" "$site"; done
for pkg in antlr4 dm_env hoptorch hydra importlib_metadata lazy_importer omegaconf pyvers; do
  cp -r "$SP/$pkg" "$SP"/"$pkg"*.dist-info "$site"/ 2>/dev/null || cp -r "$SP/$pkg" "$site"/
done
cp -r "$SP"/antlr4_python3_runtime-*.dist-info "$SP"/hydra_core-*.dist-info "$site"/
rm -rf "$site"/{benchmarks,scripts,sota-check,sota-implementations} \
  "$site"/dm_control/{locomotion,blender,suite/dog_assets,mujoco/testing} \
  "$site"/mujoco/experimental "$site"/mujoco/_render_filament*.so
assets="$site/gymnasium_robotics/envs/assets"
mkdir -p "$assets/stls"
cp "$SP/gymnasium_robotics/__init__.py" "$site/gymnasium_robotics/"
cp -r "$SP/gymnasium_robotics/envs/assets/hand" "$SP/gymnasium_robotics/envs/assets/textures" "$assets/"
cp -r "$SP/gymnasium_robotics/envs/assets/stls/hand" "$assets/stls/"
find "$site" -name __pycache__ -prune -exec rm -rf {} +
mkdir -p .devsite
tar czf .devsite/site.tgz -C "$site" .
echo "wrote .devsite/site.tgz ($(du -h .devsite/site.tgz | cut -f1))"
