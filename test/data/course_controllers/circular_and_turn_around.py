from controller import Robot

# Create the Robot instance
robot = Robot()

# Get simulation time step
timestep = int(robot.getBasicTimeStep())

# Get motors
left_motor = robot.getDevice("left wheel motor")
right_motor = robot.getDevice("right wheel motor")

# Set motors to velocity control mode
left_motor.setPosition(float('inf'))
right_motor.setPosition(float('inf'))

# Initial speeds
left_speed = 0.0
right_speed = 0.0

# Maximum motor speed (depends on robot)
MAX_SPEED = 6.28 # rad/s

# Main control loop
while robot.step(timestep) != -1:

    # ----- Motion selection -----

    # 2. Rotate in place (uncomment to test)
    left_speed = 0.5 * MAX_SPEED
    right_speed = -0.5 * MAX_SPEED

    # 3. Circular motion (uncomment to test)
    left_speed = 0.3 * MAX_SPEED
    right_speed = 0.6 * MAX_SPEED

    # Send commands to motors
    left_motor.setVelocity(left_speed)
    right_motor.setVelocity(right_speed)
