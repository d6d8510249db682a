"""Responses shared by several routes: files (downloads with ``ETag``) and documented error answers."""

from __future__ import annotations

from typing import Any

from fastapi import Response

from service.results.downloads import Download

NOT_SUCCEEDED: dict[int | str, dict[str, Any]] = {409: {"description": "The job has not succeeded."}}
DELETED: dict[int | str, dict[str, Any]] = {
    204: {"description": "Deleted, with everything derived from it."},
    409: {
        "description": "Not deleted: a job on it is queued or running, or (an MDP) a task or recording "
        "still uses it; `detail` says which (problem+json)."
    },
}
NO_SUCH_JOB: dict[int | str, dict[str, Any]] = {404: {"description": "No such job in your lab."}}


def file_response(download: Download) -> Response:
    """The file with its media type, ``Content-Disposition`` and ``ETag``; an empty 304 when not modified."""
    headers = {"Content-Disposition": f'{download.disposition}; filename="{download.filename}"'}
    if download.etag is not None:
        headers |= {"ETag": download.etag, "Cache-Control": "private, no-cache"}
    if download.content is None:
        return Response(status_code=304, headers=headers)
    return Response(download.content, media_type=download.media_type, headers=headers)
