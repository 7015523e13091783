"""Participants for what is not a cosim node: foreign ROS 2 programs (their launch and their
proxy) and the external node that brings outside messages in at tick boundaries."""
