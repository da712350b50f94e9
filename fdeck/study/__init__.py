"""Studies and identification: a layer above ``fdeck run`` that varies decks and collects their summaries.

``deck_paths`` reads and sets values by deck path, ``models`` holds the STUDY.yaml / IDENT.yaml cards, ``variants``
expands a study into resolved decks, ``executor`` runs them (local process pool or Dask) with a cache keyed by each
resolved deck's digest, ``study`` forms references and errors, ``report`` writes the tables and the plot, and
``identify`` fits deck parameters to measured data. Nothing here reaches into the engine.
"""
