"""The job lifecycle: `status` (the transition table), `config`, `submit` (checks and the queued row),
`transitions` (conditional, fenced writes shared by the API, the worker and the reaper), `queue` (the seam
the API sends through), `broker` (Celery settings), `rewards` (what a succeeded job produced).

Like `service.store`, nothing here commits: the caller that opened the session does.
"""
