#!/usr/bin/python3
"""Counts test cases in JUnit XML folders (gtest, rosunit, rostest) and prints the failed ones.

catkin_test_results gives the verdict, but it counts a gtest file's suites and cases together;
this counts each <testcase> once. Prints `passed failed skipped` on the last line."""
import pathlib
import sys
import xml.etree.ElementTree as ET

passed = failed = skipped = 0
for folder in sys.argv[1:]:
    for path in sorted(pathlib.Path(folder).rglob('*.xml')):
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as err:
            print(f'unreadable result file {path}: {err}', file=sys.stderr)
            failed += 1
            continue
        for case in root.iter('testcase'):
            name = f"{case.get('classname', '')}.{case.get('name', '')}"
            if case.find('failure') is not None or case.find('error') is not None:
                failed += 1
                print(f'FAILED {name} ({path.name})', file=sys.stderr)
            elif case.find('skipped') is not None or case.get('status') == 'notrun':
                skipped += 1
            else:
                passed += 1
print(passed, failed, skipped)
