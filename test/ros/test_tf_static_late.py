#!/usr/bin/python3
"""tf_static_late.test: a late tf listener sees the static frames of a dqo_make_scene bag.

Renders the `tiny` scene into a bag, plays it slowly with `rosbag play` (as rosbag.launch does),
starts a tf listener only after the bag's /tf_static went out, and looks up camera_base ->
rgb_camera_link: latched in the bag's connection header, rosbag play re-publishes it latched, so the
late listener gets it. Without the latch the lookup times out.
"""
import os
import shutil
import signal
import subprocess
import tempfile
import time
import unittest

import rospkg
import rospy
import tf2_ros


class TfStaticLate(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="dqo_tf_static_")
        self.player = None

    def tearDown(self):
        if self.player and self.player.poll() is None:
            self.player.send_signal(signal.SIGINT)
            try:
                self.player.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.player.kill()
        shutil.rmtree(self.dir, ignore_errors=True)

    def test_late_listener_gets_static_frames(self):
        scene = os.path.join(rospkg.RosPack().get_path("dqo_map"), "config", "scenes", "tiny.yaml")
        bag = os.path.join(self.dir, "tiny.bag")
        subprocess.run(["rosrun", "dqo_map", "dqo_make_scene", scene, os.path.join(self.dir, "data"), "--bag", bag,
                        "--frames", "10"], check=True, stdout=subprocess.DEVNULL)
        # 10 frames at 30 Hz played at 5 % speed: about 7 s of playing, /tf_static sent at its start.
        self.player = subprocess.Popen(["rosbag", "play", "--quiet", "--rate=0.05", bag],
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        rospy.init_node("test_tf_static_late", anonymous=True)
        time.sleep(3.0)  # the bag's /tf_static went out before anyone listened
        self.assertIsNone(self.player.poll(), "rosbag play ended before the late listener started")
        buffer = tf2_ros.Buffer()
        tf2_ros.TransformListener(buffer)
        t = buffer.lookup_transform("camera_base", "rgb_camera_link", rospy.Time(0), rospy.Duration(3.0))
        self.assertEqual(t.header.frame_id, "camera_base")
        self.assertEqual(t.child_frame_id, "rgb_camera_link")


if __name__ == "__main__":
    import rostest
    rostest.rosrun("dqo_map", "tf_static_late", TfStaticLate)
