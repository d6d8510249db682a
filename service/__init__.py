"""The metairl service: everything the API process and the workers share (never imports torch).

Rooms:

- `service.api`: HTTP — the app factory, routes, request/response schemas, dependencies, auth,
  pagination, problem+json handlers, OpenAPI, the body-size and idempotency middleware.
- `service.store`: the database — engine, sessions and migrations, table models, blobs, and the data
  functions of each resource (labs and keys, MDPs, demonstrators, tasks, demonstrations, recordings).
- `service.jobs`: the job lifecycle — statuses and transitions, config, submission checks, the fenced
  conditional writes, the queue seam and the broker settings, the rewards a job produced.
- `service.files`: bytes in and out — `.npz` and CSV uploads, `.npy`/CSV/JSON downloads, PNG images.
- `service.settings`, `service.problems`: the settings and the one exception hierarchy every room uses.

Imports: `service` imports the numpy-only modules of `metairl_engine` and nothing else of ours (never
`worker`, `metairl_cli` or `metairl_client`); `tests/test_layering.py` checks it.

Transactions: whoever opens the session commits — a route (the request is the unit of work), the
idempotency middleware, a worker task, a CLI command. The functions of `service.store` and
`service.jobs` take a session, add, update and flush, and never commit or roll back.
"""
