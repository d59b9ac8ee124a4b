#!/usr/bin/env python3
"""Source times that let a build cache outside the clone serve a fresh clone.

Cargo decides whether a workspace crate is stale by comparing its sources' modification times
with what it built. A fresh clone gives every file the time of the clone, so every crate of the
workspace would be rebuilt even where nothing changed. This keeps, in the cache, each tracked
file's content hash (git's blob id) and the time it was given:

  mtimes.py CACHE   files whose content is the one recorded get the recorded time back; any
                    other file (changed, new, or modified in the working tree) keeps the time
                    it has, later than anything built from another content, so Cargo rebuilds
                    what depends on it. Then the record is replaced by what this run builds
                    from, before anything is built: a run that stops half-way leaves a record
                    that matches what it built.

Only content decides: a commit's dates play no part (a commit made before the last build would
otherwise look older than it). Files modified in the working tree are neither restored nor
recorded. Run from the repository's top, before the first build.
"""

import json
import os
import subprocess
import sys


def tracked():
    """(path, blob id) of every tracked file whose working-tree content is the index's."""
    dirty = set(
        subprocess.run(
            ["git", "diff", "--name-only", "-z"], check=True, capture_output=True
        ).stdout.decode().split("\0")
    )
    out = subprocess.run(
        ["git", "ls-files", "-s", "-z"], check=True, capture_output=True
    ).stdout.decode()
    for entry in filter(None, out.split("\0")):
        meta, path = entry.split("\t", 1)
        blob = meta.split()[1]
        if path not in dirty and os.path.isfile(path):
            yield path, blob


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: mtimes.py CACHE_DIR")
    cache = sys.argv[1]
    manifest = os.path.join(cache, "mtimes.json")
    try:
        with open(manifest) as f:
            record = json.load(f)
    except (OSError, ValueError):
        record = {}
    files = list(tracked())
    same = 0
    for path, blob in files:
        old = record.get(path)
        if old and old[0] == blob:
            os.utime(path, ns=(old[1], old[1]))
            same += 1
    new = {p: [b, os.stat(p).st_mtime_ns] for p, b in files}
    os.makedirs(cache, exist_ok=True)
    with open(manifest + ".new", "w") as f:
        json.dump(new, f)
    os.replace(manifest + ".new", manifest)
    print(f"mtimes: {same} of {len(files)} files unchanged since the cache's last run")


if __name__ == "__main__":
    main()
