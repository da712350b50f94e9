"""Result sinks: VTU+PVD and XDMF+HDF5 frame series, the history CSV and the run summary JSON.

Every file is written so that a run killed at any moment (even by SIGKILL) leaves what it had finished readable:
index files (``.pvd``, ``.xdmf``, ``summary.json``) and VTU frames are replaced atomically (temporary file in the
same folder, then ``os.replace``), the HDF5 file is closed after every frame, and each history row is one
``write()`` of a complete line. Nothing here imports from ``deck/``, ``compile/`` or ``engine/``.

* :mod:`fdeck.io.frames`: ``VtuSeries``, ``XdmfSeries``, ``open_series``.
* :mod:`fdeck.io.history`: ``HistoryWriter``, ``read_history``.
* :mod:`fdeck.io.summary`: ``write_json_atomic``, ``atomic_write_bytes``, ``atomic_write_text``.
"""
