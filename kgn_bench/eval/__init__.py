"""Offline evaluation of grasp detectors on the PS dataset (the paper's vision metrics: ``vision``)."""
