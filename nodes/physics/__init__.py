"""cosim physics node: the MuJoCo world, robots and arms, odometry, TF and IMU."""
