"""The project's own measured experiments, run from a checkout as ``python experiments/...``.

Each folder holds one experiment: its sweep files and grid script, its pre-registered criteria
(``criteria.py``, one function per rule) and the table that applies them (``table.py``). None of it
is installed with the library; the tests import it from here (``tests/experiments/``).
"""
