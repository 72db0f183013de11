#!/usr/bin/python3
"""Waits until a ROS run of dqo_map has mapped everything it was given (scripts/demo).

Follows the mapping nodelet's /diagnostics: prints progress every few seconds, and returns 0 once
the bag player (`--player`, a node name) has finished and every keyframe received is mapped
(none queued, none waiting for its objects, the count steady for `--settle` seconds), 1 on timeout,
2 when the mapping nodelet never reports. Wall-clock waits only: the bag's /clock stops with it.
"""
import argparse
import sys
import time

import rosnode
import rospy
from diagnostic_msgs.msg import DiagnosticArray


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--player", default="/player")
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--settle", type=float, default=3.0)
    parser.add_argument("--every", type=float, default=5.0, help="seconds between progress lines")
    args = parser.parse_args(rospy.myargv()[1:])

    rospy.init_node("dqo_demo_wait", anonymous=True, disable_signals=True)
    latest = {}

    def on_diagnostics(msg):
        for status in msg.status:
            if status.name.startswith("dqo_map: mapping"):
                latest.clear()
                latest.update({kv.key: kv.value for kv in status.values})
                latest["_level"] = status.level
                latest["_message"] = status.message

    rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics, queue_size=10)
    start = time.time()
    last_print = 0.0
    steady_since = None
    steady_value = None
    player_done_at = None
    while time.time() - start < args.timeout:
        time.sleep(0.5)
        now = time.time()
        if not latest:
            if now - start > 60.0:
                print("[demo] the mapping nodelet publishes no diagnostics: see the launch log", flush=True)
                return 2
            continue
        try:
            player_running = args.player in rosnode.get_node_names()
        except rosnode.ROSNodeIOException:
            player_running = False
        if not player_running and player_done_at is None:
            player_done_at = now
        received = int(latest.get("keyframes received", "0"))
        mapped = int(latest.get("keyframes mapped", "0"))
        queued = int(latest.get("keyframes queued", "0"))
        waiting = int(latest.get("keyframes waiting for objects", "0"))
        dropped = int(latest.get("keyframes dropped", "0"))
        if now - last_print >= args.every:
            last_print = now
            print("[demo] %5.0f s  bag %s  keyframes: %d received, %d mapped, %d queued, %d dropped; %s Gaussians, "
                  "%s objects, %s ms per keyframe" % (now - start, "playing" if player_running else "done",
                                                     received, mapped, queued, dropped,
                                                     latest.get("gaussians", "?"), latest.get("objects", "?"),
                                                     latest.get("ms per update (mean of last 50)", "?")), flush=True)
        value = (received, mapped)
        if player_done_at is None or queued > 0 or waiting > 0 or received == 0:
            steady_since = None
            continue
        if value != steady_value:
            steady_value, steady_since = value, now
        elif now - steady_since >= args.settle and now - player_done_at >= args.settle:
            print("[demo] mapping done: %d keyframes mapped, %d dropped, %s Gaussians, %s objects" %
                  (mapped, dropped, latest.get("gaussians", "?"), latest.get("objects", "?")), flush=True)
            return 0
    print("[demo] timed out after %.0f s" % args.timeout, flush=True)
    return 1


if __name__ == "__main__":
    sys.exit(main())
