"""The ceco command: runs the node stack as supervised processes, records rosbag2 bags, replays them, reports energy and comfort."""
