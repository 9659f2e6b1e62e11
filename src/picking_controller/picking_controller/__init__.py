"""Joint trajectory controller: samples a JointTrajectory at the controller clock period."""
