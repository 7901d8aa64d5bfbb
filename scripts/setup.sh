#!/usr/bin/env bash
# Idempotent set-up: system packages, the project's virtual environment, and
# PyNumero's ASL library (needed by Pyomo's cyipopt interface), built inside the venv.
# Prints what it installs; installs nothing that is already there.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
PY=${PYTHON:-python3.11}
EXTRAS=${EXTRAS:-dev}
# ASL for PyNumero; pango/harfbuzz/fonts for WeasyPrint (PDF reports)
APT_PKGS="libamplsolver-dev cmake g++ libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz-subset0 fonts-dejavu-core ${APT_EXTRA:-}"

need_apt=""
for p in $APT_PKGS; do
  dpkg -s "$p" >/dev/null 2>&1 || need_apt="$need_apt $p"
done
if [ -n "$need_apt" ]; then
  echo "setup: installing system packages:$need_apt"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $need_apt >/dev/null
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup: creating virtual environment $VENV"
  command -v "$PY" >/dev/null || PY=python3
  "$PY" -m venv "$VENV"
fi

stamp="$VENV/.ocdsl-installed-$EXTRAS"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "setup: installing ocdsl[$EXTRAS] into $VENV"
  # this machine's pip config names local mirrors that may be absent: hide those warnings only
  "$VENV/bin/python" -m pip install -q --upgrade pip 2>&1 | { grep -v "is ignored: it is neither" || true; }
  "$VENV/bin/python" -m pip install -q -e ".[$EXTRAS]" 2>&1 | { grep -v "is ignored: it is neither" || true; }
  touch "$stamp"
fi

export PYOMO_CONFIG_DIR="$PWD/$VENV/share/pyomo"
if ! ls "$PYOMO_CONFIG_DIR"/lib/libpynumero_ASL* >/dev/null 2>&1; then
  echo "setup: building PyNumero's ASL library into $PYOMO_CONFIG_DIR"
  mkdir -p "$PYOMO_CONFIG_DIR"
  "$VENV/bin/python" - <<'PYEOF' >/dev/null
from pyomo.contrib.pynumero.build import build_pynumero
build_pynumero(['-DASL_INCLUDE_DIR=/usr/include/ampl-netlib-solvers',
                '-DASL_LIBRARY=/usr/lib/x86_64-linux-gnu/libamplsolver.so'])
PYEOF
fi
