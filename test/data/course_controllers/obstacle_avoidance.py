from controller import Robot

# Create robot instance
robot = Robot()
timestep = int(robot.getBasicTimeStep())

# Motors
left_motor = robot.getDevice("left wheel motor")
right_motor = robot.getDevice("right wheel motor")

left_motor.setPosition(float('inf'))
right_motor.setPosition(float('inf'))

MAX_SPEED = 6.28

# e-puck distance sensors
ps_names = ["ps0", "ps1", "ps2", "ps3", "ps4", "ps5", "ps6", "ps7"]
ps = []

for name in ps_names:
    sensor = robot.getDevice(name)
    sensor.enable(timestep)
    ps.append(sensor)

# Obstacle detection threshold
THRESHOLD = 80.0

while robot.step(timestep) != -1:
    # Read all proximity sensors
    values = [sensor.getValue() for sensor in ps]
    # Default motion: forward
    left_speed = 0.5 * MAX_SPEED
    right_speed = 0.5 * MAX_SPEED
    # Obstacle in front (ps0, ps1, ps6, ps7)
    if (values[0] > THRESHOLD or values[1] > THRESHOLD or
        values[6] > THRESHOLD or values[7] > THRESHOLD):
        left_speed = -0.4 * MAX_SPEED
        right_speed = 0.4 * MAX_SPEED
    # Obstacle on the right (ps2)
    elif values[2] > THRESHOLD:
        left_speed = 0.5 * MAX_SPEED
        right_speed = 0.2 * MAX_SPEED
    # Obstacle on the left (ps5)
    elif values[5] > THRESHOLD:
        left_speed = 0.2 * MAX_SPEED
        right_speed = 0.5 * MAX_SPEED
    # Apply motor commands
    left_motor.setVelocity(left_speed)
    right_motor.setVelocity(right_speed)
