"""ROS 2 glue shared by the ceco nodes: topics, QoS, parameters, message conversions, node main."""
