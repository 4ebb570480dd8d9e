"""Stage 2, scene: a scenario file as data (objects, domino runs, joints, events, free
parameters), its design space, layout files, and the posed bodies of one layout."""
