import functools, os, sys
import fabric_fenicsx.surrogate.table as table
order = int(os.environ.get("SUR_ORDER", "3"))
res = float(os.environ.get("SUR_RES", "0.002"))
table.Surrogate = functools.partial(table.Surrogate, order=order, resolution=res)
import fabric_fenicsx.impact.simulation  # noqa
from fabric_fenicsx.cli import main
sys.exit(main(sys.argv[1:]))
