"""``python -m mapassoc``: the ``mapassoc`` command (:func:`mapassoc.apps.launch.main`)."""

import sys

from mapassoc.apps.launch import main

if __name__ == "__main__":
    sys.exit(main())
