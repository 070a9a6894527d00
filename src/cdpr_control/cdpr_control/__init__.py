"""Cable robot model (kinematics, tension distribution, dynamics), trajectories and the PD + feed-forward controller."""
