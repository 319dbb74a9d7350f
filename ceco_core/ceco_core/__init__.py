"""Pure shared core of ceco (no ROS): units, psychrometrics, maths backend, comfort, contracts, metrics, run-directory format."""
