from controller import Robot

# Create the Robot instance
robot = Robot()

# Get simulation time step
timestep = int(robot.getBasicTimeStep())

# Get motors
left_motor = robot.getDevice("left wheel motor")
right_motor = robot.getDevice("right wheel motor")

# Velocity control mode
left_motor.setPosition(float('inf'))
right_motor.setPosition(float('inf'))

# Motor parameters
MAX_SPEED = 6.28 # rad/s

# Time parameters (in seconds)
FORWARD_TIME = 5.0 # time to go straight
TURN_TIME = 1.0 # time to turn 90 degrees (to adjust experimentally)

# State variables
state = "FORWARD"
state_start_time = robot.getTime()

# Main control loop
while robot.step(timestep) != -1:

    current_time = robot.getTime()
    elapsed_time = current_time - state_start_time

    if state == "FORWARD":
        # Move straight
        left_motor.setVelocity(0.5 * MAX_SPEED)
        right_motor.setVelocity(0.5 * MAX_SPEED)

        if elapsed_time >= FORWARD_TIME:
            state = "TURN"
            state_start_time = current_time

    elif state == "TURN":
        # Turn on the spot (left turn)
        left_motor.setVelocity(-0.3 * MAX_SPEED)
        right_motor.setVelocity(0.3 * MAX_SPEED)

        if elapsed_time >= TURN_TIME:
            state = "FORWARD"
            state_start_time = current_time
