"""``reference/run-directory.md``: the files of a run directory (``rgmcad optimize --run DIR``),
named by the constants the code writes them with; what each holds is said here."""

from __future__ import annotations

from rgmcad.cli.export import RUN_FILES
from rgmcad.making.ball_mass import CACHE_FILE as BALL_MASS
from rgmcad.reference.text import table
from rgmcad.runs.lock import LOCK_FILE
from rgmcad.runs.outputs import LAYOUT_FILE, START_FILE
from rgmcad.runs.report import HAND_PLOT, PROGRESS_PLOT, REPORT_FILE, ROBUSTNESS_PLOT, SLICE_PLOT
from rgmcad.runs.store import MODEL, REJECTED, RESULT, SETTINGS, SIMULATIONS
from rgmcad.viewer.report import REPORT_HTML, TEMPLATE_FILES

RUN = "the optimisation"
COMMAND = "the command, after it"


def files() -> list[tuple[str, str, str]]:
    """(name, who writes it, what it holds) of every file a run directory may hold, in the
    order they appear."""
    cad = {name: f"the optimised layout as one CAD assembly "
                 f"({'STEP, in mm' if name.endswith('.step') else name.rpartition('.')[2].upper()})"
                 "; if the export fails the run is still saved, and a warning names `rgmcad "
                 "export`" for name in RUN_FILES}
    what = {
        SETTINGS: (RUN, "what the run is: the scenario's name and the SHA-256 of its file, the "
                   "seed and the learning settings. Written once; a later command on the "
                   "folder must match it or is refused"),
        LOCK_FILE: (RUN, "held while a command has the folder open, so that one process at a "
                    "time works in it; it records who holds it"),
        SIMULATIONS: (RUN, "one JSON line per finished simulation (design vector, validity, "
                      "outcome, each event's label and time), written as they finish: an "
                      "interrupted run, started again, simulates only what is missing"),
        REJECTED: (RUN, "only when the folder is opened again and `" + SIMULATIONS + "` holds "
                   "lines that are not simulation records: they are moved here"),
        MODEL: (RUN, "the learnt success model (a Python pickle: loading one can run code, so "
                "open only run folders you trust)"),
        LAYOUT_FILE: (RUN, "the optimised layout and its placement tolerances in real units: "
                      "give it to `--layout` of `simulate`, `render`, `template`, `evaluate` "
                      "and `export`"),
        START_FILE: (RUN, "the explored layout with the highest predicted success, where the "
                     "refinement started"),
        SLICE_PLOT: (RUN, "predicted success through the layout along the two parameters it "
                     "depends on most"),
        ROBUSTNESS_PLOT: (RUN, "predicted success when every part is placed with a random "
                          "error, against the size of the error"),
        PROGRESS_PLOT: (RUN, "the exploration: whole-chain successes as the simulations went"),
        HAND_PLOT: (RUN, "only with `--hand` (on by default): success when a person builds "
                    "it, by simulation"),
        REPORT_FILE: (RUN, "the report as text"),
        RESULT: (RUN, "the summary, written last: its presence marks the run finished (a "
                 "finished run asked again shows it without simulating)"),
        REPORT_HTML: (COMMAND, "the page of the run: a 3D replay of the layout, its events, "
                      "placement tolerances, figures, bill of materials and assembly steps; "
                      "open it in a browser"),
        BALL_MASS: ("`tools/ball_mass.py`", "only once measured: how far off a ball's mass "
                    "may be before the built-by-hand figure drops, which the template's and "
                    "the report's bill of materials read"),
        **{name: (COMMAND, text) for name, text in cad.items()},
    }
    return [(name, who, text) for name, (who, text) in what.items()]



def page() -> str:
    rows = files()
    stem = LAYOUT_FILE.rpartition(".")[0]  # evaluate names its plot after the layout file
    return "\n".join([
        "# Run directory", "",
        "`rgmcad optimize SCENARIO --run DIR` keeps everything of one optimisation run in "
        "`DIR` (without `--run`: the folder its [help](cli.md#optimize) names). The run can "
        "be interrupted at any time: the same command goes on where it stopped, and a "
        "finished run is shown again without simulating.", "",
        table(["file", "written by", "what it holds"],
              [(f"`{name}`", who, text) for name, who, text in rows]), "",
        f"`{REPORT_HTML}` links a printable template it finds in the folder as it is written, "
        "at " + " or ".join(f"`{t}`" for t in TEMPLATE_FILES)
        + ": `rgmcad template SCENARIO --layout DIR/" + LAYOUT_FILE + " --out DIR/"
        + TEMPLATE_FILES[0].split("/")[0] + "` writes the first, and the same `rgmcad "
        "optimize` command writes the page again.", "",
        f"`rgmcad evaluate SCENARIO --layout DIR/{LAYOUT_FILE}` puts its plot next to the "
        f"layout: `{stem}-hand.png`, or `{stem}-robustness.png` with `--rho-g` (`--out` "
        "chooses another file).", ""])
