"""The contracts every layer shares, at the bottom of the package: the settings of a run (one
declaration per field) and the layout of a run directory. Imports nothing else of gentlerl."""
