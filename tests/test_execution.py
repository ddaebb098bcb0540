"""The execution distances have one home: the task config's defaults are those constants."""

from kgn_bench.config import ExecutionConfig
from kgn_bench.execution import GRASP_DEPTH, PREGRASP_DISTANCE


def test_execution_config_defaults_are_the_constants():
    cfg = ExecutionConfig()
    assert cfg.pregrasp_distance == PREGRASP_DISTANCE == 0.10
    assert cfg.grasp_depth == GRASP_DEPTH == 0.01
