"""Kinematic simulator of the picking arm: the servo loop of the paper's Fig. 1."""
