"""KUKA RobotSensorInterface (RSI): driving a real KR500 from the live loop.

xml       the controller's state message and the external reply (IPOC, axis angles, deg)
motion    the loop's command segments played on the controller's cycle (`MotionFollower`)
driver    the driver process: answers the controller every interpolation cycle (4 or 12 ms)
link      the loop's side: starts the driver, sends segments, trims the pacer's rate
emulator  a stand-in controller on a UDP socket, for tests and benchmarks
"""
