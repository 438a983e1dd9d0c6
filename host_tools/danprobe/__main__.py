"""python -m danprobe"""

import sys

from danprobe.cli import main

sys.exit(main())
