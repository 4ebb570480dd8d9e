import sys

from rgmcad.cli import main

sys.exit(main())
