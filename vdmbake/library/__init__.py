"""Baking an asset library (issue 24): many scenes per call over local worker processes (batch.py) or a Dask
cluster (cluster.py), a content-addressed part cache shared by scenes, processes and machines (cache.py), and a
generated library of small scenes to test them on (scenes.py); docs/library.md."""
