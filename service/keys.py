"""Creating labs and API keys (the `metairl keys create --lab NAME` command)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from service.auth import format_key, hash_secret, new_key_parts
from service.db import make_engine, migrate
from service.ids import new_id
from service.models.labs import ApiKey, Lab
from service.settings import get_settings


def create_key(session: Session, lab_name: str) -> str:
    """Create lab `lab_name` if new and a new key for it; commits and returns the key (shown only once)."""
    lab = session.execute(select(Lab).where(Lab.name == lab_name)).scalar_one_or_none()
    if lab is None:
        lab = Lab(id=new_id("lab"), name=lab_name)
        session.add(lab)
        session.flush()
    key_id, secret = new_key_parts()
    session.add(ApiKey(id=key_id, lab_id=lab.id, secret_sha256=hash_secret(secret)))
    session.commit()
    return format_key(key_id, secret)


def create_key_command(*, lab: str) -> int:
    """Migrate the configured database, create the key and print it alone on the last line; exit code."""
    if not lab.strip():
        print("error: --lab must not be empty")
        return 2
    engine = make_engine(get_settings())
    try:
        migrate(engine)
        with Session(engine) as session:
            key = create_key(session, lab.strip())
    finally:
        engine.dispose()
    print(f"Created an API key for lab {lab.strip()!r}. Send it as 'Authorization: Bearer <key>':")
    print(key)
    return 0
