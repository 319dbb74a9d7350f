"""Pure shared core of ceco (no ROS).

Units, psychrometrics, maths backend, comfort, contracts, metrics, run-directory format.
"""
