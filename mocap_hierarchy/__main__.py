"""``python -m mocap_hierarchy`` runs the command line."""

import sys

from mocap_hierarchy.cli import main

sys.exit(main())
