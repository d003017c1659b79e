"""Where the IMU is and how it moves: the site, the turntable programmes and their exact kinematics."""
