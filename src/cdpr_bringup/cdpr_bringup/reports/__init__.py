"""What a run or a robot looks like afterwards: `cdpr-report` and its plots, `cdpr-robot`,
and `cdpr-fdi-offline` (the twin and supervisor replayed on a bag).

Rooms it may import: runs, bags.
"""
