# Sourced by tools/adaproj and tools/test: make sure the virtual environment exists and
# holds the project with the extras the calling script needs. The script sets `extras`
# before sourcing: "" (tools/adaproj: the package and what running it needs) or "dev"
# (tools/test: every extra, the test and lint tools). Creates the environment on first
# use (a fresh machine) and installs again when pyproject.toml changes or the set asked
# for is not there yet, saying what it does on stderr: a line per stage, pip's own
# progress, the time it took. A stamp per set records the pyproject.toml it came from;
# the "dev" set holds the base one too.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${ADAPROJ_VENV:-$repo/.venv}"
extras="${extras:-}"
stamp_for() { if [ "$1" = dev ]; then echo "$venv/.installed-from"; else echo "$venv/.installed-from-base"; fi; }
want="$(sha256sum "$repo/pyproject.toml" | cut -d' ' -f1)"
have() { [ "$(cat "$(stamp_for "$1")" 2>/dev/null)" = "$want" ]; }
if [ ! -x "$venv/bin/python" ] || ! { have "$extras" || have dev; }; then
  started=$SECONDS
  if [ ! -x "$venv/bin/python" ]; then
    echo "adaproj: first run: installing the project into $venv (a few minutes)" >&2
    echo "adaproj: [1/3] creating the virtual environment" >&2
    python3 -m venv "$venv"
  else
    if [ -e "$(stamp_for "$extras")" ]; then
      echo "adaproj: pyproject.toml changed: updating $venv" >&2
    else
      echo "adaproj: adding what ${0##*/} needs to $venv" >&2
    fi
    echo "adaproj: [1/3] the virtual environment is there" >&2
  fi
  echo "adaproj: [2/3] updating pip" >&2
  "$venv/bin/python" -m pip install --upgrade --progress-bar on pip >&2
  # no byte-compiling of every installed file (thousands): Python compiles what it imports
  if [ "$extras" = dev ]; then
    echo "adaproj: [3/3] installing adaproj-edge with every extra and the test tools" \
      "(numpy, scipy, OpenCV, onnxruntime, DepthAI, NVIDIA Warp, pytest, ruff, mypy)" >&2
    "$venv/bin/python" -m pip install --no-compile --progress-bar on -e "$repo[dev]" >&2
  else
    echo "adaproj: [3/3] installing adaproj-edge and what it needs to run" \
      "(numpy, scipy, OpenCV, onnxruntime)" >&2
    "$venv/bin/python" -m pip install --no-compile --progress-bar on -e "$repo" >&2
  fi
  echo "$want" > "$(stamp_for "$extras")"
  echo "adaproj: $venv ready in $((SECONDS - started)) s" >&2
fi
export PATH="$venv/bin:$PATH"
