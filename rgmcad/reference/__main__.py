"""``python -m rgmcad.reference``: the generated reference pages as one JSON object."""

import json
import sys

from rgmcad.reference import pages

json.dump(pages(), sys.stdout)
