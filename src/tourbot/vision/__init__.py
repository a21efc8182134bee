"""Obstacles the laser cannot see, found with the forward camera (Burgard et al., Sec. 3)."""
