"""Infrastructure shared by the three packages, not physics: atomic writes, checked ``.npz``
files, the content-addressed disk cache, the bounded in-memory LRU and lazy JIT compilation.

Private to the project (``sensors``, ``aas_gym``, ``real`` import it); users need none of it.
"""
