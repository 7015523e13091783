"""CDR (the ROS 2 wire format): canonical bytes, and generated encoders and decoders."""
