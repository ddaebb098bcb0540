"""Layers import one way: decoding, training and the dataset format load no simulator."""

import subprocess
import sys

import pytest


@pytest.mark.parametrize("module", ["kgn_bench.model.decode", "kgn_bench.training.train", "kgn_bench.data.format",
                                    "kgn_bench.types"])
def test_module_loads_no_simulator(module):
    code = (f"import sys, {module}; "
            "print(','.join(m for m in ('mujoco', 'dm_control', 'mink', 'kgn_bench.sim.scene') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"{module} loads {out}"
