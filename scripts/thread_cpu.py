#!/usr/bin/env python3
"""How much of a core each thread of a running ROS node uses, measured from /proc over a wall-clock window.

Usage: thread_cpu.py [--seconds S] [--json FILE] NODE
       e.g. thread_cpu.py --seconds 30 /bullet_sim

Asks the ROS master (ROS_MASTER_URI) for the node's process, reads each thread's user + system time from
/proc/PID/task/*/stat at the start and the end of the window, and prints one line per thread name (threads of one
name summed: roscpp's spinners, for instance; the main thread on its own line, "NAME (main)") with its share of one
core, then the process's total (from /proc/PID/stat: threads that ended in the window included). bullet_sim names
its threads: its main thread runs the control loop, sim_states the joint states and /clock, sim_scene the markers,
~cloth and the cameras' images (roscpp's threads keep the process's name). Exits 1 with the reason when the master,
the node or its process cannot be reached, or the node runs on another machine."""
import argparse
import json
import os
import socket
import sys
import time
import urllib.parse
import xmlrpc.client


def node_pid(node):
    master = xmlrpc.client.ServerProxy(os.environ.get("ROS_MASTER_URI", "http://localhost:11311"))
    code, message, uri = master.lookupNode("/thread_cpu", node)
    if code != 1:
        raise RuntimeError(f"the master does not know node '{node}': {message}")
    host = urllib.parse.urlparse(uri).hostname
    local = {"localhost", socket.gethostname(), socket.getfqdn()}
    try:
        addresses = {socket.gethostbyname(host)}
    except OSError:
        addresses = set()
    if host not in local and not any(a.startswith("127.") for a in addresses):
        raise RuntimeError(f"node '{node}' runs on {host}, not on this machine: run this there")
    code, message, pid = xmlrpc.client.ServerProxy(uri).getPid("/thread_cpu")
    if code != 1:
        raise RuntimeError(f"node '{node}' did not give its process id: {message}")
    return int(pid)


def cpu_seconds(stat_path):
    """(name, user + system seconds) from a /proc stat file."""
    with open(stat_path, encoding="utf-8") as f:
        stat = f.read()
    name = stat[stat.index("(") + 1:stat.rindex(")")]
    fields = stat[stat.rindex(")") + 2:].split()  # from field 3 on: utime and stime are fields 14 and 15
    return name, (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def thread_times(pid):
    """{tid: (name, user + system seconds)} of every thread of the process, the main thread's name marked."""
    times = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            name, seconds = cpu_seconds(f"/proc/{pid}/task/{tid}/stat")
        except OSError:
            continue  # the thread ended
        times[tid] = (name + " (main)" if tid == str(pid) else name, seconds)
    return times


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("node", help="the node's name, e.g. /bullet_sim")
    parser.add_argument("--seconds", type=float, default=20.0, help="the window of wall-clock time (default 20)")
    parser.add_argument("--json", help="also write the shares to this file")
    args = parser.parse_args()
    if not 0.5 <= args.seconds <= 3600.0:
        parser.error("--seconds must lie in [0.5, 3600]")
    try:
        pid = node_pid(args.node)
        start, process_start, wall_start = thread_times(pid), cpu_seconds(f"/proc/{pid}/stat")[1], time.monotonic()
        time.sleep(args.seconds)
        end, process_end = thread_times(pid), cpu_seconds(f"/proc/{pid}/stat")[1]
        wall = time.monotonic() - wall_start
    except (OSError, RuntimeError, ConnectionError, xmlrpc.client.Error) as e:
        print(f"thread_cpu.py: {e}", file=sys.stderr)
        return 1
    shares = {}
    for tid, (name, seconds) in end.items():
        shares[name] = shares.get(name, 0.0) + (seconds - start.get(tid, (name, 0.0))[1]) / wall
    print(f"thread_cpu.py: {args.node} (pid {pid}) over {wall:.1f} s of wall time, share of one core:")
    for name, share in sorted(shares.items(), key=lambda kv: -kv[1]):
        print(f"  {name:<22} {100.0 * share:6.1f} %")
    total = (process_end - process_start) / wall
    print(f"  {'(process)':<22} {100.0 * total:6.1f} %")
    if args.json:
        try:
            with open(args.json, "w", encoding="utf-8") as f:
                json.dump({"node": args.node, "wall_seconds": wall, "threads": shares, "process": total}, f, indent=1)
        except OSError as e:
            print(f"thread_cpu.py: cannot write {args.json}: {e}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
