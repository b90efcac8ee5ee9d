"""``python -m dashboard_node``: ``aes-dashboard`` that always prints its URL with the token
on stdout, for the terminal of its owner (``aes-swarm dashboard`` runs it so)."""

import sys

from dashboard_node.node import main

if __name__ == "__main__":
    sys.exit(main(print_url=True))
