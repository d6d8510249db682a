"""What each resource looks like over HTTP and inside the service: pydantic request and response bodies, one module
per resource (names follow docs/api.md), and the enums they use.

Below the data functions (`service.store`), the files (`service.files`), the job lifecycle (`service.jobs`) and the
HTTP layer (`service.api`), which all import it; it imports only the tables (`service.store.models`) and the engine's
numpy-only modules. A response is built from its row by ``XOut.of(row)``, the one way a row becomes a response.
"""
