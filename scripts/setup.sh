#!/usr/bin/env bash
# Installs what the project needs on a fresh Debian 12 machine (as root) into .venv/.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
# chromium: the headless browser the `garment view` test loads Rerun's web viewer in.
for pkg in build-essential python3-dev libsuitesparse-dev libopenblas0-pthread libosmesa6 chromium; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ]; then
    echo "installing Debian packages: ${need_apt[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$PYTHON" -m venv .venv
fi
stamp=.venv/.installed-$(cat pyproject.toml scripts/constraints.txt | sha1sum | cut -c1-12)
if [ ! -f "$stamp" ]; then
    .venv/bin/python -m pip install -q --upgrade pip
    # Exact versions (scripts/constraints.txt): a fresh machine gets what the docs measured.
    .venv/bin/python -m pip install -q -c scripts/constraints.txt -e ".[test]"
    rm -f .venv/.installed-* && touch "$stamp"
fi
