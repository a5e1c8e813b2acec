"""`tutti` (and `python -m tutti`): runs the executable this wheel carries, in this process's
place, so that signals, the exit status and the terminal are the executable's own."""

import os
import sys

from tutti import bin_path


def main():
    exe = bin_path()
    try:
        os.execv(exe, [exe] + sys.argv[1:])
    except OSError as e:
        sys.stderr.write(f"tutti: cannot run {exe}: {e}\n")
        return 1


if __name__ == "__main__":
    sys.exit(main())
