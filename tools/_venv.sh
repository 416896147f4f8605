# Sourced by tools/adaproj and tools/test: make sure .venv exists and holds the project.
# Creates it on first use (a fresh machine) and re-installs when pyproject.toml changes,
# saying what it does on stderr: a line per stage, pip's own progress, the time it took.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${ADAPROJ_VENV:-$repo/.venv}"
stamp="$venv/.installed-from"
want="$(sha256sum "$repo/pyproject.toml" | cut -d' ' -f1)"
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  started=$SECONDS
  if [ ! -x "$venv/bin/python" ]; then
    echo "adaproj: first run: installing the project into $venv (a few minutes)" >&2
    echo "adaproj: [1/3] creating the virtual environment" >&2
    python3 -m venv "$venv"
  else
    echo "adaproj: pyproject.toml changed: updating $venv" >&2
    echo "adaproj: [1/3] the virtual environment is there" >&2
  fi
  echo "adaproj: [2/3] updating pip" >&2
  "$venv/bin/python" -m pip install --upgrade --progress-bar on pip >&2
  echo "adaproj: [3/3] installing adaproj-edge and its dependencies (numpy, scipy," \
    "OpenCV, onnxruntime, DepthAI, test and lint tools)" >&2
  "$venv/bin/python" -m pip install --progress-bar on -e "$repo[dev]" >&2
  echo "$want" > "$stamp"
  echo "adaproj: $venv ready in $((SECONDS - started)) s" >&2
fi
export PATH="$venv/bin:$PATH"
