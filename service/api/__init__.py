"""HTTP: the app factory (`service.api.app:create_app`), routes, schemas, dependencies and error handling.

A route is the unit of work of its request: it calls `service.store`/`service.jobs` functions (which never
commit), commits, then turns rows into responses with the schema's ``XOut.of(row)``. Routes share
dependencies and responses through `service.api.deps`, never by importing another route.
"""
