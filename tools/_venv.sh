# Sourced by tools/adaproj and tools/test: make sure .venv exists and holds the project.
# Creates it on first use (a fresh machine) and re-installs when pyproject.toml changes.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${ADAPROJ_VENV:-$repo/.venv}"
stamp="$venv/.installed-from"
want="$(sha256sum "$repo/pyproject.toml" | cut -d' ' -f1)"
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "adaproj: preparing $venv (first run installs the dependencies, a few minutes)..." >&2
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --upgrade pip >&2
  "$venv/bin/python" -m pip install --quiet -e "$repo[dev]" >&2
  echo "$want" > "$stamp"
fi
export PATH="$venv/bin:$PATH"
