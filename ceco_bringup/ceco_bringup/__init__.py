"""The ceco command: runs the node stack as supervised processes.

It also records rosbag2 bags, replays them and reports energy and comfort.
"""
