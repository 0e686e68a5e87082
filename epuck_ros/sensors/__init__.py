"""The e-puck's senses beyond the IR ring, each a part computed only while wanted: camera, ground sensors,
light sensors, accelerometer and gyro over a Scene (the world with its appearance), the e-puck2's ToF."""
