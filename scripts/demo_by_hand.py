#!/usr/bin/python3
"""Runs the README's "First run, by hand" as written and checks it (scripts/demo --by-hand).

The bash blocks between the README's `by-hand:begin` and `by-hand:end` markers are the commands a
user types: block 1 in terminal 1 (the launch, left running), block 2 in terminal 2 while the bag
plays, block 3 there once mapping has caught up. Each line runs as written from the repository's
folder, in a shell that sourced what the block's `source` lines source, with two things set as a
user's environment could set them: ROS_HOME (a folder of this run's own, so ~/.ros is left alone)
and ROS_MASTER_URI (a port of its own, so a roscore already running elsewhere is not disturbed).
One substitution: `extract_object "{id: 2, ...}"` takes the first ID `list_objects` printed (IDs
depend on the order candidates appeared). Exit 0 when every line did what the README says.
"""
import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import time


def by_hand_blocks(readme):
    text = open(readme).read()
    begin = text.index("<!-- by-hand:begin")
    end = text.index("<!-- by-hand:end")
    blocks = re.findall(r"```bash\n(.*?)```", text[begin:end], flags=re.S)
    out = []
    for b in blocks:
        lines = [l.split("  #")[0].rstrip() for l in b.splitlines()]
        out.append([l for l in lines if l and not l.lstrip().startswith("#")])
    return out


def say(text):
    print("[by-hand] " + text, flush=True)


class Terminal:
    """A terminal: the lines of `source` it ran, prepended to each command."""

    def __init__(self, repo, env):
        self.repo, self.env, self.sourced = repo, env, []

    def script(self, line):
        return "\n".join(self.sourced + [line])

    def run(self, line, timeout=120):
        if line.startswith("source "):
            self.sourced.append(line)
            return 0, ""
        say("$ " + line)
        p = subprocess.run(["bash", "-c", self.script(line)], cwd=self.repo, env=self.env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, timeout=timeout, text=True)
        for l in p.stdout.splitlines()[:12]:
            print("    " + l, flush=True)
        return p.returncode, p.stdout


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repo", required=True)
    parser.add_argument("--ws", required=True)
    parser.add_argument("--home", required=True, help="this run's folder (ROS_HOME, logs); emptied first")
    parser.add_argument("--port", type=int, default=11812)
    parser.add_argument("--timeout", type=float, default=900.0)
    args = parser.parse_args()

    blocks = by_hand_blocks(os.path.join(args.repo, "README.md"))
    if len(blocks) != 3:
        say("README.md: expected 3 bash blocks between the by-hand markers, found %d" % len(blocks))
        return 2
    shutil.rmtree(args.home, ignore_errors=True)
    os.makedirs(args.home)
    env = dict(os.environ)
    env["ROS_HOME"] = os.path.join(args.home, "ros_home")
    env["ROS_MASTER_URI"] = "http://localhost:%d" % args.port
    env["ROSCONSOLE_STDOUT_LINE_BUFFERED"] = "1"
    log_path = os.path.join(args.home, "terminal1.log")
    failures = []

    # Terminal 1: the launch, left running.
    t1 = Terminal(args.repo, env)
    for line in blocks[0][:-1]:
        t1.run(line)
    say("$ " + blocks[0][-1] + "   (terminal 1, log: %s)" % log_path)
    log = open(log_path, "w")
    launch = subprocess.Popen(["bash", "-c", t1.script("exec " + blocks[0][-1])], cwd=args.repo, env=env,
                              stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        # A user reads terminal 1 before typing in terminal 2: wait for its master (roslaunch starts one).
        t2 = Terminal(args.repo, env)
        for line in blocks[1]:
            if line.startswith("source "):
                t2.run(line)
        deadline = time.time() + 60
        while subprocess.run(["bash", "-c", t2.script("rosnode list")], env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL).returncode != 0:
            if time.time() > deadline or launch.poll() is not None:
                failures.append("terminal 1 started no ROS master within 60 s (see %s)" % log_path)
                break
            time.sleep(1)
        # Terminal 2 while the bag plays.
        for line in blocks[1] if not failures else []:
            if line.startswith("source "):
                continue
            rc, out = t2.run(line)
            if "tf_echo" in line:
                ok = "Translation:" in out  # `timeout` ends it: 124 is its normal end
            else:
                ok = rc == 0 and out.strip() != ""
            if not ok:
                failures.append("%s (exit %d)" % (line, rc))
        # Until mapping has caught up: the mapping nodelet's diagnostics, as scripts/demo waits.
        waited = failures or subprocess.run(["bash", "-c", t2.script("/usr/bin/python3 %s --timeout %d" % (
            os.path.join(args.repo, "scripts", "demo_wait.py"), args.timeout))], cwd=args.repo, env=env).returncode
        if failures:
            pass
        elif waited != 0:
            failures.append("mapping did not catch up (see %s)" % log_path)
        else:
            ids = []
            for line in blocks[2]:
                if "extract_object" in line and ids:
                    line = re.sub(r"id: *\d+", "id: %s" % ids[0], line)
                rc, out = t2.run(line)
                if line.startswith("source "):
                    continue
                if "list_objects" in line:
                    ids = re.findall(r"^\s*-?\s*id: (\d+)", out, flags=re.M)
                    ok = rc == 0 and len(ids) > 0
                elif "extract_object" in line:
                    ok = rc == 0 and "success: True" in out
                else:
                    ok = rc == 0
                if not ok:
                    failures.append("%s (exit %d)" % (line, rc))
    finally:
        # Ctrl-C in terminal 1.
        if launch.poll() is None:
            os.killpg(launch.pid, signal.SIGINT)
            try:
                launch.wait(timeout=40)
            except subprocess.TimeoutExpired:
                failures.append("roslaunch did not end within 40 s of Ctrl-C")
                os.killpg(launch.pid, signal.SIGKILL)
        log.close()
    text = open(log_path).read()
    if "[FATAL]" in text:
        failures.append("terminal 1 printed a FATAL line (see %s)" % log_path)
    if failures:
        for f in failures:
            say("FAILED: " + f)
        return 1
    n = sum(1 for b in blocks for l in b if not l.startswith("source "))
    say("all %d commands of the README's by-hand run did what it says (terminal 1: %s)" % (n, log_path))
    return 0


if __name__ == "__main__":
    sys.exit(main())
