#!/usr/bin/python3
"""The ROS system's sustained rate on a bag played in real time (BENCHMARKS.md).

Run beside `roslaunch dqo_map rosbag.launch bag:=...` (it waits for the first keyframe, so start it
first). It listens to what the stages publish and reports, once the bag is over and the mapping
nodelet is idle:
  - input frames and keyframes (the tracker's), keyframes mapped and dropped (the mapping nodelet's
    diagnostics);
  - latency from a keyframe to its objects: wall time from the KeyFrame's arrival to the arrival of
    the association node's KeyFrameObjects for it (median, 90 %, max);
  - latency from a keyframe to its Gaussians: to the first diagnostics message that counts it as
    mapped (resolution: the diagnostics period) or drops it.

  bench_ros_system.py [--timeout S] [--player /player]
"""
import argparse
import statistics
import sys
import threading
import time

import rosnode
import rospy
from diagnostic_msgs.msg import DiagnosticArray
from dqo_map.msg import KeyFrame, KeyFrameObjects
from sensor_msgs.msg import CameraInfo


def pct(values, q):
    if not values:
        return float("nan")
    v = sorted(values)
    return v[min(len(v) - 1, int(q * (len(v) - 1) + 0.5))]


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--timeout", type=float, default=900.0)
    parser.add_argument("--player", default="/player")
    args = parser.parse_args(rospy.myargv()[1:])
    rospy.init_node("bench_ros_system", anonymous=True, disable_signals=True)
    lock = threading.Lock()
    kf_arrival = {}       # keyframe id -> wall time
    kfo_latency = []      # seconds
    mapped_latency = []
    order = []            # keyframe ids in arrival order
    frames = [0, None, None]  # count, first wall, last wall
    diag = {}

    def on_info(_):
        with lock:
            now = time.time()
            frames[0] += 1
            frames[1] = frames[1] or now
            frames[2] = now

    def on_kf(msg):
        with lock:
            kf_arrival[msg.id] = time.time()
            order.append(msg.id)

    def on_kfo(msg):
        with lock:
            t = kf_arrival.get(msg.keyframe_id)
            if t is not None:
                kfo_latency.append(time.time() - t)

    def on_diag(msg):
        for s in msg.status:
            if not s.name.startswith("dqo_map: mapping"):
                continue
            values = {kv.key: kv.value for kv in s.values}
            with lock:
                diag.update(values)
                done = int(values.get("keyframes mapped", 0)) + int(values.get("keyframes dropped", 0))
                now = time.time()
                while len(mapped_latency) < min(done, len(order)):
                    mapped_latency.append(now - kf_arrival[order[len(mapped_latency)]])

    rospy.Subscriber("/rgb/camera_info", CameraInfo, on_info, queue_size=100)
    rospy.Subscriber("/dqo_map/keyframes", KeyFrame, on_kf, queue_size=100)
    rospy.Subscriber("/dqo_map/keyframe_objects", KeyFrameObjects, on_kfo, queue_size=100)
    rospy.Subscriber("/diagnostics", DiagnosticArray, on_diag, queue_size=100)
    start = time.time()
    player_seen = False
    while time.time() - start < args.timeout:
        time.sleep(0.5)
        try:
            running = args.player in rosnode.get_node_names()
        except rosnode.ROSNodeIOException:
            running = False
        player_seen = player_seen or running
        with lock:
            received = int(diag.get("keyframes received", 0))
            done = int(diag.get("keyframes mapped", 0)) + int(diag.get("keyframes dropped", 0))
            queued = int(diag.get("keyframes queued", 1))
        if player_seen and not running and received > 0 and done >= received and queued == 0:
            break
    with lock:
        fps = (frames[0] - 1) / (frames[2] - frames[1]) if frames[0] > 1 else float("nan")
        print("input frames: %d at %.1f/s" % (frames[0], fps))
        print("keyframes: %d published by tracking, %s received / %s mapped / %s dropped by mapping"
              % (len(order), diag.get("keyframes received"), diag.get("keyframes mapped"),
                 diag.get("keyframes dropped")))
        print("mapping: %s ms per keyframe (mean of the last 50), %s Gaussians, peak memory %s MB"
              % (diag.get("ms per update (mean of last 50)"), diag.get("gaussians"),
                 diag.get("peak resident memory (MB)")))
        print("keyframe -> its objects (association): median %.0f ms, 90%% %.0f ms, max %.0f ms over %d"
              % (1e3 * statistics.median(kfo_latency) if kfo_latency else float("nan"),
                 1e3 * pct(kfo_latency, 0.9), 1e3 * max(kfo_latency or [float("nan")]), len(kfo_latency)))
        print("keyframe -> mapped or dropped (mapping): median %.1f s, 90%% %.1f s, max %.1f s over %d"
              % (statistics.median(mapped_latency) if mapped_latency else float("nan"),
                 pct(mapped_latency, 0.9), max(mapped_latency or [float("nan")]), len(mapped_latency)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
