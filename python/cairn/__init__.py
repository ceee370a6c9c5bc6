"""Cairn: fast, g2o-compatible factor-graph optimisation and cone SLAM.

Read a g2o file or build a graph from numpy arrays, solve it, and take the
estimate out as arrays::

    import cairn
    graph = cairn.read_g2o("city10000.g2o")
    summary = graph.optimize(solver="gn", init="file")
    poses = graph.se2_array()          # rows (id, x, y, theta)

Errors carry Cairn's message: ValueError for bad input, OSError for files,
RuntimeError for a solve that cannot be carried out.
"""

from ._cairn import Graph, Summary, __version__, fs_sim, fs_slam, read_g2o

__all__ = ["Graph", "Summary", "read_g2o", "fs_slam", "fs_sim", "__version__"]
