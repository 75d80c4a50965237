# Sourced by the Blender tests, with their arguments BUILD_DIR WORK_DIR:
# strict mode, $build and $work from them (the work folder made), $here this
# folder and $data the test assets.
set -euo pipefail
build=$1
work=$2
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
data=$here/../data
mkdir -p "$work"
