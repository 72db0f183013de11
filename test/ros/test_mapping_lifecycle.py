#!/usr/bin/python3
"""The mapping nodelet's life beside a long mapping step (issue 26), on keyframes this test makes
and publishes itself (no tracker, no bag): the nodelet runs in a nodelet manager that the test
starts, as launch/mapping.launch does, so that it can send the manager SIGINT and time its exit.

One run, in order (each step needs the one before):
  1. a small keyframe is mapped (a step of a fraction of a second);
  2. the `gaussians` cloud and the `map_render` are latched: a subscriber that connects after they
     went out gets them;
  3. a large keyframe starts a step of minutes (many iterations on 640x480; CPU, one thread):
     while it runs, /diagnostics of the nodelet come at their configured rate, and say so;
  4. SIGINT to the manager during that step: it exits cleanly within shutdown_timeout and a few
     seconds (roslaunch escalates to SIGTERM after 15 s), having written the autosave after the
     signal, holding both keyframes (the long step cut short);
  5. a new manager resumes from that autosave (dqo::mapping::load_map_file): 2 keyframes.
And through roslaunch (launch/mapping.launch: a manager and a `nodelet load` client, as a user runs
it): SIGINT to roslaunch during a long step ends it without "escalating to SIGTERM", with the
autosave written.
"""
import math
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
import unittest

import numpy as np
import roslib.packages
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from dqo_map.msg import KeyFrame, KeyFrameObjects
from sensor_msgs.msg import Image, PointCloud2
from std_msgs.msg import String

# The nodelet tool (Debian: /usr/lib/nodelet/nodelet; ROS distributions: lib/nodelet/nodelet).
NODELET = (roslib.packages.find_node('nodelet', 'nodelet') or ['/usr/lib/nodelet/nodelet'])[0]
NS = '/dqo_map_lifecycle'   # a namespace of its own: nothing else in the test graph listens
DIAG_PERIOD = 0.25
SHUTDOWN_TIMEOUT = 3.0
ESCALATION_S = 15.0         # roslaunch's DEFAULT_TIMEOUT_SIGINT (roslaunch/nodeprocess.py)


def image(width, height, encoding, data):
    msg = Image(width=width, height=height, encoding=encoding, is_bigendian=0)
    msg.step = data.strides[0]
    msg.data = data.tobytes()
    return msg


def keyframe(kf_id, stamp, width, height):
    """A textured plane 1.5 m in front of the camera, seen from a pose shifted with the ID."""
    msg = KeyFrame()
    msg.header.stamp = rospy.Time.from_sec(stamp)
    msg.header.frame_id = 'map'
    msg.id = kf_id
    msg.pose.position.x = 0.02 * kf_id
    msg.pose.orientation.w = 1.0
    f = 0.8 * width
    info = msg.camera_info
    info.header = msg.header
    info.width, info.height = width, height
    info.distortion_model = 'plumb_bob'
    info.D = [0.0] * 5
    info.K = [f, 0, width / 2.0, 0, f, height / 2.0, 0, 0, 1]
    info.R = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    info.P = [f, 0, width / 2.0, 0, 0, f, height / 2.0, 0, 0, 0, 1, 0]
    v, u = np.mgrid[0:height, 0:width]
    rgb = np.zeros((height, width, 3), np.uint8)
    rgb[..., 0] = (127 + 100 * np.sin(u * 12.0 / width)).astype(np.uint8)
    rgb[..., 1] = (127 + 100 * np.cos(v * 9.0 / height)).astype(np.uint8)
    rgb[..., 2] = ((u // 8 + v // 8) % 2 * 200).astype(np.uint8)
    depth = np.full((height, width), 1.5, np.float32) + 0.1 * (u / width).astype(np.float32)
    msg.rgb = image(width, height, 'rgb8', rgb)
    msg.depth = image(width, height, '32FC1', depth)
    msg.rgb.header = msg.depth.header = msg.header
    return msg


def keyframe_objects(kf):
    """No detections: the keyframe is ready at once, all background."""
    msg = KeyFrameObjects()
    msg.header = kf.header
    msg.keyframe_id = kf.id
    msg.detections.header = kf.header
    return msg


class Process:
    """A child process with its output in a file (read by the checks)."""

    def __init__(self, args, log_path, ns=NS):
        # Line-buffered: the checks read the output while the process runs.
        env = dict(os.environ, ROSCONSOLE_STDOUT_LINE_BUFFERED='1')
        if ns:
            env['ROS_NAMESPACE'] = ns
        self.log_path = log_path
        self.log = open(log_path, 'w')
        self.proc = subprocess.Popen(args, stdout=self.log, stderr=subprocess.STDOUT, env=env)

    def text(self):
        with open(self.log_path) as f:
            return f.read()

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(ESCALATION_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()


class TestMappingLifecycle(unittest.TestCase):
    def setUp(self):
        self.work = tempfile.mkdtemp(prefix='dqo_lifecycle_')
        self.lock = threading.Lock()
        self.diags = []  # (arrival wall time, {key: value})
        self.procs = []
        rospy.set_param(NS + '/mapping', {
            'output_dir': self.work,
            'autosave_period': 0.0,          # only at shutdown: the file then comes from it
            'diagnostics_period': DIAG_PERIOD,
            'gaussians_period': 0.5,
            'render_period': 0.5,
            'shutdown_timeout': SHUTDOWN_TIMEOUT,
            'idle_flush': 60.0,
            # One CPU thread (the test machine has two cores) and enough iterations that a
            # 640x480 keyframe's step runs for minutes; the small first keyframe's for < 1 s.
            'mapping': {'backend': 'cpu', 'threads': 1, 'max_queue': 0, 'objects_timeout': 1000.0,
                        'trainer': {'iterations': 3000, 'newest_share': 0.9}},
        })
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diag, queue_size=100)
        self.advertise(NS)

    def advertise(self, ns):
        """The nodelet's inputs in namespace ns (its diagnostics are those of ns/mapping)."""
        self.ns = ns
        self.kf_pub = rospy.Publisher(ns + '/keyframes', KeyFrame, queue_size=10, latch=True)
        self.obj_pub = rospy.Publisher(ns + '/keyframe_objects', KeyFrameObjects, queue_size=10, latch=True)
        self.id_pub = rospy.Publisher(ns + '/map_id', String, queue_size=1, latch=True)
        self.id_pub.publish(String(data='lifecycle'))

    def tearDown(self):
        for p in reversed(self.procs):
            p.stop()
        if not os.environ.get('DQO_TEST_KEEP'):
            shutil.rmtree(self.work, ignore_errors=True)

    def start_manager(self, tag):
        manager = Process([NODELET, 'manager', '__name:=manager_' + tag],
                          os.path.join(self.work, 'manager_%s.log' % tag))
        self.procs.append(manager)
        loader = Process([NODELET, 'load', 'dqo_map/MappingNodelet', 'manager_' + tag, '__name:=mapping'],
                         os.path.join(self.work, 'load_%s.log' % tag))
        self.procs.append(loader)
        return manager

    def on_diag(self, msg):
        for s in msg.status:
            if s.name == 'dqo_map: mapping ' + self.ns + '/mapping':
                with self.lock:
                    self.diags.append((time.time(), {kv.key: kv.value for kv in s.values}))

    def latest(self):
        with self.lock:
            return self.diags[-1][1] if self.diags else None

    def wait_for(self, what, predicate, timeout):
        deadline = time.time() + timeout
        while time.time() < deadline and not rospy.is_shutdown():
            d = self.latest()
            if d is not None and predicate(d):
                return d
            time.sleep(0.05)
        self.fail('timed out after %.0f s waiting for %s (last diagnostics: %s)' % (timeout, what, self.latest()))

    def send(self, kf):
        self.obj_pub.publish(keyframe_objects(kf))
        self.kf_pub.publish(kf)

    def test_lifecycle(self):
        manager = self.start_manager('a')
        self.wait_for('the nodelet', lambda d: True, 30)
        time.sleep(1.0)  # the nodelet's subscribers connect to the latched inputs

        # 1. A small keyframe, mapped quickly.
        self.send(keyframe(1, 1000.0, 32, 24))
        self.wait_for('keyframe 1 mapped', lambda d: int(d['keyframes mapped']) >= 1, 30)

        # 2. Latched cloud: published once after the step (nothing is mapped after it), then a
        # subscriber that connects late still gets it.
        time.sleep(2.0)
        clouds = []
        sub = rospy.Subscriber(NS + '/gaussians', PointCloud2, clouds.append)
        deadline = time.time() + 5.0
        while not clouds and time.time() < deadline:
            time.sleep(0.05)
        sub.unregister()
        self.assertEqual(len(clouds), 1, 'a late subscriber to gaussians got %d clouds' % len(clouds))
        self.assertGreater(clouds[0].width, 0)

        # 2b. Latched render: a subscriber makes the nodelet render the map; one that connects after
        # it left (a restarted rviz) gets that render at once instead of "No Image".
        renders = []
        sub = rospy.Subscriber(NS + '/map_render', Image, renders.append)
        deadline = time.time() + 10.0
        while not renders and time.time() < deadline:
            time.sleep(0.05)
        sub.unregister()
        self.assertTrue(renders, 'no map_render within 10 s of subscribing')
        late = []
        sub = rospy.Subscriber(NS + '/map_render', Image, late.append)
        deadline = time.time() + 3.0
        while not late and time.time() < deadline:
            time.sleep(0.05)
        sub.unregister()
        self.assertTrue(late, 'a late subscriber to map_render got nothing')
        self.assertEqual((late[0].width, late[0].height), (renders[-1].width, renders[-1].height))

        # 3. A long step: diagnostics keep their rate while it runs.
        self.send(keyframe(2, 1001.0, 640, 480))
        self.send(keyframe(3, 1002.0, 640, 480))
        self.wait_for('the step of keyframe 2', lambda d: float(d['mapping step in progress (s)']) > 0.5, 30)
        t0 = time.time()
        time.sleep(3.0)
        with self.lock:
            window = [d for t, d in self.diags if t0 <= t < t0 + 3.0]
        expected = 3.0 / DIAG_PERIOD
        self.assertGreaterEqual(len(window), 0.7 * expected,
                                '%d diagnostics in 3 s during a mapping step (period %.2f s)' % (len(window), DIAG_PERIOD))
        for d in window:  # the step was running the whole window, and the counters are current
            self.assertGreater(float(d['mapping step in progress (s)']), 0.0)
            self.assertEqual(d['keyframes mapped'], '1')
            self.assertGreater(int(d['gaussians']), 0)

        # 4. SIGINT during the step: a quick exit that saves.
        self.assertIsNone(manager.proc.poll())
        signalled = time.time()
        manager.proc.send_signal(signal.SIGINT)
        try:
            rc = manager.proc.wait(ESCALATION_S)
        except subprocess.TimeoutExpired:
            self.fail('the manager did not exit within %.0f s of SIGINT (roslaunch would escalate to SIGTERM)'
                      % ESCALATION_S)
        took = time.time() - signalled
        log = manager.text()
        self.assertEqual(rc, 0, log[-3000:])
        self.assertLess(took, SHUTDOWN_TIMEOUT + 5.0, 'exit took %.1f s' % took)
        autosave = os.path.join(self.work, 'autosave.dqomap')
        self.assertTrue(os.path.exists(autosave), log[-3000:])
        self.assertGreaterEqual(os.path.getmtime(autosave), signalled - 0.01)
        m = re.search(r'saved the map \((\d+) keyframes, (\d+) Gaussians\)', log)
        self.assertIsNotNone(m, log[-3000:])
        self.assertEqual(int(m.group(1)), 2, 'keyframe 2 (cut short) is in the map, 3 (queued) is not')
        self.assertIn('cut short', log)
        rospy.loginfo('manager exited %.1f s after SIGINT: %s', took, m.group(0))

        # 5. The autosave loads (load_map_file) and a new nodelet resumes from it.
        manager_b = self.start_manager('b')
        deadline = time.time() + 30.0
        resumed = None
        while resumed is None and time.time() < deadline:
            resumed = re.search(r'resumed (\d+) Gaussians and (\d+) keyframes', manager_b.text())
            time.sleep(0.1)
        self.assertIsNotNone(resumed, manager_b.text()[-3000:])
        self.assertEqual(int(resumed.group(2)), 2)
        self.assertEqual(int(resumed.group(1)), int(m.group(2)))

    def test_roslaunch_sigint(self):
        """SIGINT to roslaunch (mapping.launch) during a long step: no escalation, the autosave written."""
        config = os.path.join(self.work, 'slow.yaml')
        with open(config, 'w') as f:
            f.write('mapping:\n  backend: cpu\n  threads: 1\n  objects_timeout: 1000.0\n'
                    '  trainer:\n    iterations: 3000\n    newest_share: 0.9\n')
        self.advertise('/dqo_map')
        log_path = os.path.join(self.work, 'roslaunch.log')
        launch = Process(['roslaunch', 'dqo_map', 'mapping.launch', 'config:=' + config, 'output_dir:=' + self.work,
                          'max_queue:=0', 'fresh:=true', 'output:=screen'], log_path, ns=None)
        self.procs.append(launch)
        self.wait_for('the nodelet', lambda d: True, 40)
        time.sleep(1.0)
        self.send(keyframe(1, 1000.0, 32, 24))
        self.wait_for('keyframe 1 mapped', lambda d: int(d['keyframes mapped']) >= 1, 30)
        self.send(keyframe(2, 1001.0, 640, 480))
        self.wait_for('the step of keyframe 2', lambda d: float(d['mapping step in progress (s)']) > 0.5, 30)
        signalled = time.time()
        launch.proc.send_signal(signal.SIGINT)
        try:
            launch.proc.wait(2 * ESCALATION_S)
        except subprocess.TimeoutExpired:
            self.fail('roslaunch still running %.0f s after SIGINT:\n%s' % (2 * ESCALATION_S, launch.text()[-3000:]))
        took = time.time() - signalled
        out = launch.text()
        self.assertNotIn('escalating', out, out[-3000:])
        autosave = os.path.join(self.work, 'autosave.dqomap')
        self.assertTrue(os.path.exists(autosave), out[-3000:])
        self.assertGreaterEqual(os.path.getmtime(autosave), signalled - 0.01)
        self.assertRegex(out, r'saved the map \(2 keyframes, \d+ Gaussians\)')
        rospy.loginfo('roslaunch ended %.1f s after SIGINT', took)


if __name__ == '__main__':
    rospy.init_node('test_mapping_lifecycle')
    rostest.rosrun('dqo_map', 'mapping_lifecycle', TestMappingLifecycle)
