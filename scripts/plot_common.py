"""What every plot script of the benchmark programs shares: its command line (one output directory; -h/--help prints
the script's doc and exits 0, anything else prints it on stderr and exits 2) and the directory's summary.json."""
import json
import os
import sys


def output_directory(doc):
    """The directory named on the command line of a script whose usage is `doc`."""
    if len(sys.argv) == 2 and sys.argv[1] in ("-h", "--help"):
        print(doc)
        sys.exit(0)
    if len(sys.argv) != 2 or sys.argv[1].startswith("-"):
        print(doc, file=sys.stderr)
        sys.exit(2)
    return sys.argv[1]


def read_summary(directory):
    """DIR/summary.json as written by the benchmark programs (program, experiment, seed, quick, results)."""
    with open(os.path.join(directory, "summary.json"), encoding="utf-8") as f:
        return json.load(f)
