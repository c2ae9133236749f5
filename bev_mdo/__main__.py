"""python -m bev_mdo == bev-mdo."""
import sys

from bev_mdo.cli import main

sys.exit(main())
