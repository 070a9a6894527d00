"""`cdpr-bench robots`: robots drawn from a seed (`draw`), each with motions inside its
wrench-feasible workspace (`motions`), calibrated and broken cable by cable through the
campaign machinery, and the stack judged on them (`judge`, `command`).

Rooms it may import: runs, campaigns.
"""
