#!/usr/bin/env python3
"""Plays a user dragging the demo cloth in RViz, for the headless screenshot
(test/node/demo_screenshot with DRAG=1): clicks beside node NODE (RViz's
Publish Point), then sends the interactive-marker feedback of a drag that
lifts the handle up and away over 2 s and keeps holding it there until killed.

    test/node/drag_demo.py [--node 300] [--node-name /cloth_sim]
"""
import argparse
import time

import rospy
from cloth_sim.msg import ClothState
from geometry_msgs.msg import PointStamped
from visualization_msgs.msg import InteractiveMarkerFeedback as Feedback


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--node", type=int, default=300)  # row 12, col 12 of the 24x24 demo
    parser.add_argument("--node-name", default="/cloth_sim")
    args = parser.parse_args()
    rospy.init_node("drag_demo", anonymous=True)
    latest = {}
    rospy.Subscriber(args.node_name + "/state", ClothState,
                     lambda m: latest.__setitem__("state", m), queue_size=1)
    click = rospy.Publisher("/clicked_point", PointStamped, queue_size=1, latch=True)
    feedback = rospy.Publisher(args.node_name + "/drag/feedback", Feedback, queue_size=10)
    time.sleep(1.0)
    # The demo cloth swings: click where the node is now.
    p = latest["state"].positions[args.node]
    msg = PointStamped()
    msg.header.frame_id = "world"
    msg.point.x, msg.point.y, msg.point.z = p.x, p.y, p.z
    click.publish(msg)
    time.sleep(0.5)
    p = latest["state"].positions[args.node]  # where the handle starts

    def send(event, x, y, z):
        f = Feedback()
        f.header.frame_id = "world"
        f.client_id = "/rviz/InteractiveMarkers"
        f.marker_name = "node_%d" % args.node
        f.control_name = "move"
        f.event_type = event
        f.pose.position.x, f.pose.position.y, f.pose.position.z = x, y, z
        f.pose.orientation.w = 1.0
        feedback.publish(f)

    send(Feedback.MOUSE_DOWN, p.x, p.y, p.z)
    start = time.time()
    print("dragging node %d" % args.node, flush=True)
    while not rospy.is_shutdown():
        s = min(1.0, (time.time() - start) / 2.0)
        send(Feedback.POSE_UPDATE, p.x - 0.35 * s, p.y + 0.25 * s, p.z + 0.45 * s)
        time.sleep(0.02)


if __name__ == "__main__":
    main()
