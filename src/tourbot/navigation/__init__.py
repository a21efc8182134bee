"""Navigation: global planner, collision avoidance among people, tour executor, site navigator."""
