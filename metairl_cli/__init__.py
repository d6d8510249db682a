"""The `metairl` command (serve, worker, keys, demo): above the service, the worker and the client.

It may import anything of ours; nothing imports it. Each subcommand loads its implementation lazily, so
`metairl keys` never loads torch or Celery.
"""
