#!/usr/bin/env bash
# The README's main job: set up (install, build), then run the demo on an embedded phantom.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh release
exec build/bin/fluoro demo "$@"
