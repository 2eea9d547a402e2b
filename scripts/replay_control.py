#!/usr/bin/env python3
"""Drives a paused `rosbag play` (replay.launch player_args:="--pause --keep-alive"): waits until
the given topics have subscribers (the visual_gyro node, rviz), starts playback through the
player's pause_playback service, and returns once the node has answered the bag's last image
(its ~orientation message) or the clock has passed the end of the bag, plus a settling time.

Usage: replay_control.py --last-stamp T [--subscribed TOPIC ...] [--player /player]
                         [--orientation /camera/visual_gyro/orientation] [--settle 2] [--timeout 300]
Exit status 0 when the bag played to its end, 1 on a timeout (with the reason on stderr)."""
import argparse
import sys
import time

import rosgraph
import rospy
from geometry_msgs.msg import PoseStamped
from rosgraph_msgs.msg import Clock
from std_srvs.srv import SetBool


def subscribers(master, topic):
    _, subs, _ = master.getSystemState()
    for name, nodes in subs:
        if name == topic:
            return nodes
    return []


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--last-stamp", type=float, required=True, help="stamp of the bag's last image [s]")
    parser.add_argument("--subscribed", action="append", default=[], help="topic that must have a subscriber first")
    parser.add_argument("--player", default="/player")
    parser.add_argument("--orientation", default="/camera/visual_gyro/orientation")
    parser.add_argument("--settle", type=float, default=2.0, help="wall seconds to wait after the end")
    parser.add_argument("--timeout", type=float, default=300.0, help="wall seconds in all")
    args = parser.parse_args(rospy.myargv()[1:])

    rospy.init_node("replay_control", anonymous=True, disable_signals=True)
    start = time.time()
    master = rosgraph.Master(rospy.get_name())

    def timed_out(what):
        if time.time() - start > args.timeout:
            sys.stderr.write("replay_control: timed out after %.0f s %s\n" % (args.timeout, what))
            sys.exit(1)

    for topic in args.subscribed:
        while not subscribers(master, topic):
            timed_out("waiting for a subscriber on %s" % topic)
            time.sleep(0.2)
    # Registered is not yet connected: give the connections a moment before the first message.
    time.sleep(1.0)

    state = {"clock": 0.0, "answered": 0.0}
    rospy.Subscriber("/clock", Clock, lambda m: state.__setitem__("clock", m.clock.to_sec()))
    rospy.Subscriber(args.orientation, PoseStamped,
                     lambda m: state.__setitem__("answered", max(state["answered"], m.header.stamp.to_sec())))
    service = args.player + "/pause_playback"
    while True:
        timed_out("waiting for %s" % service)
        try:
            rospy.wait_for_service(service, timeout=1.0)
            break
        except rospy.ROSException:
            pass
    rospy.ServiceProxy(service, SetBool)(False)
    sys.stderr.write("replay_control: playback started\n")

    # The node's outputs are stamped at the image or at the midpoint of two images: the last
    # answer's stamp comes within one frame of the last image.
    while not (state["answered"] >= args.last_stamp - 0.2 or state["clock"] >= args.last_stamp + 1.0):
        timed_out("waiting for the end of the bag (clock %.3f, last answer %.3f, last image %.3f)"
                  % (state["clock"], state["answered"], args.last_stamp))
        time.sleep(0.1)
    time.sleep(args.settle)
    sys.stderr.write("replay_control: bag played (clock %.3f, last answer %.3f)\n" % (state["clock"], state["answered"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
