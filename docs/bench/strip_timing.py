"""Reads a command's standard output; if it is JSON, drops the fields that measure time or name the temporary output files (their
names end in `_ms`, `_s` or contain `seconds`/`elapsed`) and prints the rest sorted, so outputs of
two runs can be compared by checksum. Other text passes through unchanged."""
import json
import re
import sys

TIMING = re.compile(r"(^output$|^input$|path|^ms$|_ms$|_ms_|_s$|seconds|elapsed|per_s)")


def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if not TIMING.search(k)}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v


text = sys.stdin.read()
try:
    print(json.dumps(strip(json.loads(text)), sort_keys=True, indent=1))
except ValueError:
    # Human-readable reports: drop the lines that carry timings.
    for line in text.splitlines(True):
        if not re.search(r"\d ms\b|frames/s|[0-9] s\b", line):
            sys.stdout.write(line)
