"""The database: engine and sessions (`db`), tables (`models`), migrations, blobs, and the data functions of
each resource (`mdps`, `demonstrators`, `tasks`, `demonstrations`, `recordings`, `keys`).

Data functions take a session, add, update and flush; they never commit — the caller that opened the
session does (a route, a worker task, a CLI command). They return rows, not responses.
"""
