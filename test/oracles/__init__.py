"""Independent oracles for the solver tests: closed forms of the source papers.

Nothing here imports `linkage_monitor`: an oracle must not share code with what it checks.
"""
