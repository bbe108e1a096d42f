"""Data layer: the term library (:mod:`.terms`), vehicle files (:mod:`.vehicle`) and their
``[prior]`` section (:mod:`.priors`), the Track CSV contract (:mod:`.track`), semantic checks of a
track (:mod:`.validate`) and readers of real free-running data (:mod:`.datasets`)."""
