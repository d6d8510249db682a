"""The job lifecycle (its statuses are `service.store.models.job_status`): `config`, `submit` (checks and the queued row),
`transitions` (conditional, fenced writes shared by the API, the worker and the reaper), `queue` (the seam
the API sends through), `broker` (Celery settings),
`webhooks` (deliveries of a finished job) and `reaping` (the reaper's queries). What a job produced is `service.results`.

Like `service.store`, nothing here commits: the caller that opened the session does.
"""
