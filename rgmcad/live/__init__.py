"""The live design page (``rgmcad live``): a local web server that shows a scenario's layout
simulated and replayed in 3D, and simulates it again on every save of the file, a slider
moved, a layout chosen to compare with or a sweep asked for.

:mod:`~rgmcad.live.server` serves the page and pushes the state to it (aiohttp);
:mod:`~rgmcad.live.session` holds that state and hands the simulations to the worker
process (:mod:`~rgmcad.live.worker`); :mod:`~rgmcad.live.views` makes what is shown from the
viewer's own pieces; :mod:`~rgmcad.live.files` watches the files and writes the layout file.
"""

from rgmcad.live.server import serve
from rgmcad.live.session import LiveOptions

__all__ = ["LiveOptions", "serve"]
