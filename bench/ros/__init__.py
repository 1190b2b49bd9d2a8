"""ROS bridge benchmarks: goal round trips against rclpy's and actionlib's own clients, and
the simulator behind ROS against the direct simulation."""
