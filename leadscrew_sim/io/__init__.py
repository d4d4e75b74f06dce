"""
Bytes and schemas: CDR, message definitions, the topic table, MCAP writing and reading.

Knows nothing of rclpy or of the physics: the recorder process runs on this
layer alone (``python -m leadscrew_sim.io.recorder``).
"""
