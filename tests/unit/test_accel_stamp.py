"""The compiled kernels' cache stamp follows their real sources: the files that declare a
kernel and the package modules they import names from, not the modules that only call them."""
from pathlib import Path

import mavreg
from mavreg import accel

ROOT = Path(mavreg.__file__).resolve().parent


def test_stamp_holds_the_kernel_files_and_what_they_compile_in():
    files = {str(f.relative_to(ROOT)) for f in accel._kernel_sources(ROOT)}
    for kernel in ("control/controllers/step_kernel.py", "model/rotor_lag_kernel.py", "model/drag_kernel.py",
                   "model/mixer_kernel.py", "geometry/projection_kernel.py", "sim/batch_kernel.py"):
        assert kernel in files
    assert "config/vehicle.py" in files           # gravity, compiled into the predictor and hover kernels
    # negative control: modules that only call kernels do not recompile them when edited
    for caller in ("control/controllers/hover.py", "control/controllers/fastpath.py", "control/controllers/regulator.py", "accel.py"):
        assert caller not in files


def test_a_new_kernel_file_and_its_imports_are_found(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "consts.py").write_text("K = 2\n")
    (pkg / "caller.py").write_text("from .accel import use_compiled\n")
    (pkg / "sub" / "k_kernel.py").write_text("from ..accel import njit\nfrom ..consts import K\n\n\n"
                                             "@njit\ndef f(x):\n    return K * x\n")
    (pkg / "accel.py").write_text("")
    found = {str(f.relative_to(pkg)) for f in accel._kernel_sources(pkg)}
    assert found == {"sub/k_kernel.py", "consts.py", "accel.py"}
