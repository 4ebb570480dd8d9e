"""What a person looks at: a simulated run replayed in 3D in one self-contained HTML page
(:mod:`rgmcad.viewer.page`), and an optimisation run's report page around it
(:mod:`rgmcad.viewer.report`). The stage after :mod:`rgmcad.runs`, beside printing."""
