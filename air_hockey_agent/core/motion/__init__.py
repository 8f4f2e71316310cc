"""Motion layer: arm kinematics, inverse kinematics, hit planning, task-space motions, joint trajectories."""
