"""Every table of the service; importing this package registers them all on `Base.metadata`."""

from service.store.models import (
    blobs,
    demonstrators,
    idempotency,
    jobs,
    labs,
    mdps,
    recordings,
    webhooks,
)
from service.store.models.base import Base

__all__ = ["Base", "blobs", "demonstrators", "idempotency", "jobs", "labs", "mdps", "recordings", "webhooks"]
