#!/usr/bin/python3
"""Checks the generated Python messages and services against the .msg/.srv sources, and that
`rosmsg show` / `rossrv show` know them (what a user types after building)."""
import io
import os
import re
import subprocess
import unittest

import rospkg

PKG = 'dqo_map'
BUILTIN = {'bool', 'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64',
           'float32', 'float64', 'string', 'time', 'duration'}


def parse_fields(lines):
    """(name, type) of each field of a .msg section, constants skipped, types written as genpy does."""
    fields = []
    for line in lines:
        line = line.split('#', 1)[0].strip()
        if not line or '=' in line:
            continue
        ftype, name = line.split()[:2]
        base = re.sub(r'\[.*\]$', '', ftype)
        suffix = ftype[len(base):]
        if base == 'Header':
            base = 'std_msgs/Header'
        elif base not in BUILTIN and '/' not in base:
            base = PKG + '/' + base
        fields.append((name, base + suffix))
    return fields


class TestMessages(unittest.TestCase):
    def setUp(self):
        self.root = rospkg.RosPack().get_path(PKG)

    def read(self, kind, name):
        with open(os.path.join(self.root, kind, name + '.' + kind)) as f:
            return f.read().splitlines()

    def test_messages_match_sources(self):
        import dqo_map.msg as msgs
        names = sorted(f[:-4] for f in os.listdir(os.path.join(self.root, 'msg')) if f.endswith('.msg'))
        self.assertEqual(names, sorted(['Detection', 'DetectionArray', 'KeyFrame', 'KeyFramePoses', 'Object',
                                        'ObjectArray', 'ObjectEvent', 'KeyFrameObjects']))
        for name in names:
            cls = getattr(msgs, name)
            expected = parse_fields(self.read('msg', name))
            self.assertEqual(list(zip(cls.__slots__, cls._slot_types)), expected, name)

    def test_services_match_sources(self):
        import dqo_map.srv as srvs
        for name in ['ListObjects', 'GetObject', 'ExtractObject', 'SaveMap', 'LoadMap']:
            lines = self.read('srv', name)
            cut = lines.index('---')
            for part, sect in (('Request', lines[:cut]), ('Response', lines[cut + 1:])):
                cls = getattr(srvs, name + part)
                self.assertEqual(list(zip(cls.__slots__, cls._slot_types)), parse_fields(sect), name + part)

    def test_object_round_trip(self):
        from dqo_map.msg import Object, ObjectArray, ObjectEvent
        obj = Object(id=7, class_id=3, class_name='cup', observations=12, confidence=0.75, num_gaussians=4096)
        obj.semi_axes.x, obj.semi_axes.y, obj.semi_axes.z = 0.04, 0.04, 0.05
        obj.dual_quadric = [float(i) for i in range(16)]
        arr = ObjectArray(objects=[obj])
        buf = io.BytesIO()
        arr.serialize(buf)
        out = ObjectArray().deserialize(buf.getvalue())
        self.assertEqual(out.objects[0].id, 7)
        self.assertEqual(out.objects[0].class_name, 'cup')
        self.assertEqual(list(out.objects[0].dual_quadric), list(range(16)))
        self.assertEqual((ObjectEvent.CREATED, ObjectEvent.MERGED, ObjectEvent.REMOVED), (0, 1, 2))

    def test_command_line_tools(self):
        env = dict(os.environ)
        out = subprocess.run(['rosmsg', 'show', 'dqo_map/ObjectArray'], env=env, check=True,
                             stdout=subprocess.PIPE, universal_newlines=True).stdout
        for field in ('dqo_map/Object[] objects', 'float64[16] dual_quadric', 'geometry_msgs/Vector3 semi_axes'):
            self.assertIn(field, out)
        out = subprocess.run(['rossrv', 'show', 'dqo_map/ExtractObject'], env=env, check=True,
                             stdout=subprocess.PIPE, universal_newlines=True).stdout
        for field in ('uint64 id', 'string subfolder', '---', 'string mesh_path', 'string gaussians_path'):
            self.assertIn(field, out)


if __name__ == '__main__':
    import rostest
    rostest.rosrun(PKG, 'test_messages', TestMessages)
