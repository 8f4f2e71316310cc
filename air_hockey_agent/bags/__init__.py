"""rosbag2 recordings (sqlite3 or MCAP) read and written with rosbags: no ROS installation needed."""
