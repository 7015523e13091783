"""What a run leaves behind and how it is read: the rosbag2 recording, the manifest, the report
and its picture, the USD export, and the comparison of two runs (diff)."""
