"""What every recovery shares: where the end-effector goes after a break and whether it
can (`recovery`: safe points and safe poses), and where its move is planned, at once or
beside a realtime loop (`planning`).

Rooms it may import: none.
"""
