"""``python -m aes_ros.cli`` is ``aes-swarm``."""

import sys

from aes_ros.cli import main

sys.exit(main())
