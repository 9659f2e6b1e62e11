"""Bringing the picking arm up and using it: ``picking-stack``, ``picking-goal``, ``picking-plan``, the demo
with its report, plots and recording, and the shipped parameter files (:mod:`.shipped`)."""
