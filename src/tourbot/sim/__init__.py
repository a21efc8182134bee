"""The simulator: robot, odometry error, laser, the crowd of visitors, changing doors and furniture."""
