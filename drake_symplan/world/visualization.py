"""Meshcat helpers: a live viewer on localhost and self-contained HTML recordings."""

from __future__ import annotations

import logging
from contextlib import contextmanager
from pathlib import Path

from pydrake.geometry import Meshcat, MeshcatParams


def StartMeshcat(port: int | None = None, announce: bool = True) -> Meshcat:
    """Drake's Meshcat server on localhost; prints its URL when `announce` (a server
    started only to write a recording need not say where it is)."""
    params = MeshcatParams()
    params.host = "localhost"
    if port is not None:
        params.port = port
    if announce:
        meshcat = Meshcat(params)
    else:  # Drake logs the URL at INFO, through Python's "drake" logger
        drake_log = logging.getLogger("drake")
        previous = drake_log.level
        drake_log.setLevel(logging.WARNING)
        try:
            meshcat = Meshcat(params)
        finally:
            drake_log.setLevel(previous)
    meshcat.SetCameraPose(camera_in_world=[1.9, -1.3, 1.1], target_in_world=[0.65, 0.0, 0.1])
    if announce:
        print(f"Meshcat is serving at {meshcat.web_url()}", flush=True)
    return meshcat


@contextmanager
def recording(station, path: str | Path | None):
    """Records the station's visualizer while the block runs; writes one HTML file."""
    if path is None or station.visualizer is None:
        yield
        return
    vis = station.visualizer
    vis.DeleteRecording()
    vis.StartRecording(set_transforms_while_recording=True)
    try:
        yield
    finally:
        vis.StopRecording()
        vis.PublishRecording()
        Path(path).write_text(station.meshcat.StaticHtml())
