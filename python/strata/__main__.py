"""python -m strata: the batch baker (python -m strata.batch)."""
import sys

from .batch import main

sys.exit(main())
