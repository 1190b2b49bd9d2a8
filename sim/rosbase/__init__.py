"""What the simulator behind ROS 1 and the one behind ROS 2 share: the hosts' clock check
and setup, and the robots' state link."""
