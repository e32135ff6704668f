"""Physical constants the package uses, each defined once (SI units)."""

ATMOSPHERIC_PRESSURE = 101325.0
"""Pa, ISO 2533 standard atmosphere at sea level: absolute = gauge + this (sensor_msgs/FluidPressure
carries absolute pressure)."""

STANDARD_GRAVITY = 9.80665
"""m/s², ISO 80000-3 standard acceleration of gravity (what an IMU's accelerometer reads at rest)."""
