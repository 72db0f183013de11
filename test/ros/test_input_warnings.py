#!/usr/bin/python3
"""input_warnings.test: the WARNs a user sees on /diagnostics when inputs never come.

- tracking, no images at all: WARN "no images for N s (none yet) on <the three topics>";
- association, no keyframes: WARN "no keyframes on <topic> for N s (none yet ...)";
- mapping, no keyframes: WARN "no keyframes on <topic> for N s: is tracking running ...";
- association, keyframes but no detections: WARN "keyframes arrive but no detections on ..." —
  one keyframe message (empty images: the node skips it, but it counts as arrived).
"""
import time
import unittest

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from dqo_map.msg import KeyFrame


class InputWarnings(unittest.TestCase):
    def setUp(self):
        rospy.init_node("test_input_warnings", anonymous=True)
        self.latest = {}
        rospy.Subscriber("/diagnostics", DiagnosticArray, self.on_diagnostics, queue_size=50)

    def on_diagnostics(self, msg):
        for s in msg.status:
            self.latest[s.name] = s

    def wait_for(self, name, predicate, timeout=20.0):
        """The latest status whose name starts with `name` once it satisfies predicate (or the last seen)."""
        deadline = time.time() + timeout
        found = None
        while time.time() < deadline and not rospy.is_shutdown():
            for key, s in list(self.latest.items()):
                if key.startswith(name):
                    found = s
                    if predicate(s):
                        return s
            time.sleep(0.1)
        return found

    def test_warnings(self):
        tracking = self.wait_for("dqo_map: tracking", lambda s: "no images" in s.message)
        self.assertIsNotNone(tracking, "tracking published no diagnostics")
        self.assertEqual(tracking.level, DiagnosticStatus.WARN, tracking.message)
        self.assertIn("no images", tracking.message)
        self.assertIn("none yet", tracking.message)
        self.assertIn("/rgb/image_raw", tracking.message)

        association = self.wait_for("dqo_map: association", lambda s: "no keyframes" in s.message)
        self.assertIsNotNone(association, "association published no diagnostics")
        self.assertEqual(association.level, DiagnosticStatus.WARN, association.message)
        self.assertIn("/dqo_map/keyframes", association.message)

        mapping = self.wait_for("dqo_map: mapping", lambda s: "no keyframes" in s.message, timeout=40.0)
        self.assertIsNotNone(mapping, "mapping published no diagnostics")
        self.assertEqual(mapping.level, DiagnosticStatus.WARN, mapping.message)
        self.assertIn("/dqo_map/keyframes", mapping.message)

        # Keyframes that come without detections: a different warning, naming the detections topic.
        pub = rospy.Publisher("/dqo_map/keyframes", KeyFrame, queue_size=10)
        deadline = time.time() + 10
        while pub.get_num_connections() == 0 and time.time() < deadline:
            time.sleep(0.1)
        self.assertGreater(pub.get_num_connections(), 0, "association does not subscribe to keyframes")
        for k in range(3):
            kf = KeyFrame()
            kf.header.stamp = rospy.Time.now()
            kf.id = k + 1
            pub.publish(kf)
            time.sleep(0.3)
        association = self.wait_for("dqo_map: association", lambda s: "no detections" in s.message)
        self.assertEqual(association.level, DiagnosticStatus.WARN, association.message)
        self.assertIn("/detections", association.message)
        values = {kv.key: kv.value for kv in association.values}
        self.assertEqual(values.get("detection arrays received"), "0")
        self.assertNotEqual(values.get("seconds since a keyframe"), "never")


if __name__ == "__main__":
    import rostest
    rostest.rosrun("dqo_map", "input_warnings", InputWarnings)
