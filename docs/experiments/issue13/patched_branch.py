"""The command line with material (b) of branch_patch.py (runner for pair.sh)."""
import sys
sys.path.insert(0, "/work/ens")
import branch_patch  # noqa: F401  (replaces YarnStress._intact)
from fabric_fenicsx.cli import main
sys.exit(main(sys.argv[1:]))
