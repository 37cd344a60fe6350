"""KUKA RobotSensorInterface (RSI): driving a KUKA robot, and the rail it stands on, live.

xml       the controller's state message and the external reply (IPOC, axis angles, deg)
axes      which controller axis moves each platform joint (A1-A6, a rail's E1), in its units
motion    the loop's command segments played on the controller's cycle (`MotionFollower`)
driver    the driver process: answers the controller every interpolation cycle (4 or 12 ms)
link      the loop's side: starts the driver, sends segments, trims the pacer's rate
emulator  a stand-in controller on a UDP socket, for tests and benchmarks
"""
