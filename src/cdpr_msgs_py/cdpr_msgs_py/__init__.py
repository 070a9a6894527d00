"""The cdpr interface contract in Python: topic names, QoS profiles, mode names, message <-> numpy conversions and validation."""
