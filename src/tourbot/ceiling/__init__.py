"""Global localization from ceiling lights with an upward fisheye camera (Gamallo et al.).

``camera`` (projection models), ``rig`` (the camera on the robot), ``detection`` (lights in an
image), ``merit`` (Alg. 2 and Eq. 5), ``minimize`` (Alg. 3, hypotheses), ``tracking`` (odometry
motion model between images) and ``likelihood`` (the camera as a sensor of MCL).
"""
