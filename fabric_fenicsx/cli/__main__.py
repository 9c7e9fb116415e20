"""``python -m fabric_fenicsx.cli ...``: the same as ``fabric-fenicsx ...``."""
import sys

from fabric_fenicsx.cli import main

sys.exit(main())
