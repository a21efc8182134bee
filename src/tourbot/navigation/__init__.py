"""Driving the robot on its estimate: the grid planner, collision avoidance and the tour executor."""
