"""Maps: occupancy grid, likelihood field, ray casting and beam model kernels, reference maps."""
