"""Training KGN / KGNv2: the augmented samples of a PS dataset (``dataset``) and the training driver (``train``).

It sits above ``model`` and ``data`` and below ``eval`` and ``detectors``: the driver takes its held-out
evaluator as an argument, so importing it loads neither the detectors nor the simulator.
"""
