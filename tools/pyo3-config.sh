# Sourced by tools/install.sh and tools/run-tests.sh: PyO3's build configuration for the native
# module, tools/kitti2pgm_py/pyo3-build.txt (abi3 from CPython 3.9: the same for every CPython
# interpreter that can load the module), exported as PYO3_CONFIG_FILE. maturin then uses it
# instead of writing its own, so that its build and a plain cargo build of the module (the one
# tools/run-tests.sh builds beside the tests) have the same environment and share their
# artefacts; with maturin's own file, each rebuilt PyO3 for the other. Left to maturin when the
# user set PYO3_CONFIG_FILE, or for an interpreter that abi3 does not serve (PyPy, GraalPy, a
# free-threaded CPython), where maturin configures PyO3 itself.
if [ -z "${PYO3_CONFIG_FILE:-}" ] && python3 -c 'import platform, sys, sysconfig
raise SystemExit(not (platform.python_implementation() == "CPython" and sys.version_info >= (3, 9)
                      and not sysconfig.get_config_var("Py_GIL_DISABLED")))' 2>/dev/null; then
  PYO3_CONFIG_FILE="$PWD/tools/kitti2pgm_py/pyo3-build.txt"
  export PYO3_CONFIG_FILE
fi
