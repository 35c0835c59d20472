#!/bin/sh
# `pip install` of the source tree into a fresh virtual environment (scikit-build-core and
# pybind11 fetched by pip into its build environment, NumPy and pytest from PyPI), then the Python
# tests against that installed module, run from outside the source tree with no PYTHONPATH.
# usage: pip_install_test.sh PYTHON SOURCE WORK
set -eu
python=$1 source=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
"$python" -m venv "$work/venv"
venv=$work/venv/bin
"$venv/pip" install --quiet --disable-pip-version-check "$source" pytest
cd "$work"
unset PYTHONPATH
"$venv/python" -c 'import strata, sys; print("strata", strata.__version__, "from", strata.__file__); sys.exit(not strata.__file__.startswith(sys.prefix))'
# The type stubs come with it, as the stub-only package mypy looks for.
"$venv/python" -c 'import pathlib, strata; p = pathlib.Path(strata.__file__).parent / "strata-stubs" / "__init__.pyi"; assert p.is_file(), p'
STRATA_MODELS_DIR=$source/tests/models STRATA_TEST_OUTPUT_DIR=$work/output \
  "$venv/python" -m pytest -q -p no:cacheprovider "$source/python/tests"
