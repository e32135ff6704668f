"""linkage_monitor: load monitoring of tractor hitch linkages (planar statics from sensor data)."""
