"""Rate limits: a key guesser gets 429 with `Retry-After` after a burst of 401s (a key accepted before goes on
working from its address), a key over its rate gets 429 and is let in again after `Retry-After`, a key under it
never does, and each limit is a setting (0 turns it off)."""

from __future__ import annotations

import secrets
import time
from collections.abc import Iterator
from contextlib import contextmanager

from fastapi.testclient import TestClient

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.api.ratelimit import window
from service.settings import Settings

SLOW = 0.01
"""A rate low enough that no window lets a request in again while a test runs (one every 100 s)."""


@contextmanager
def limited(settings: Settings, **limits: float) -> Iterator[tuple[TestClient, str]]:
    """A client of an app with these rate-limit settings, and a valid key of a new lab."""
    app = create_app(settings.model_copy(update=limits))
    with app.state.sessionmaker() as session:
        key = create_key(session, f"rate-{secrets.token_hex(4)}")
    try:
        with TestClient(app) as client:
            yield client, key
    finally:
        app.state.engine.dispose()


def bearer(key: str) -> dict[str, str]:
    """The Authorization header of `key`."""
    return {"Authorization": f"Bearer {key}"}


def test_a_key_guesser_gets_429_with_retry_after_once_its_failures_pass_the_burst(settings: Settings) -> None:
    with limited(settings, rate_limit_per_ip=SLOW, rate_limit_per_ip_burst=5) as (client, key):
        answers = [
            client.get("/v1/mdps", headers=bearer(f"mirl_{secrets.token_hex(8)}_{secrets.token_hex(16)}"))
            for _ in range(30)
        ]
        assert [a.status_code for a in answers] == [401] * 5 + [429] * 25
        for refusal in answers[5:]:
            assert refusal.headers["content-type"].startswith("application/problem+json")
            assert refusal.json()["type"] == "/problems/rate-limited"
            assert refusal.headers["retry-after"].isdigit() and int(refusal.headers["retry-after"]) >= 1
        # The address is refused before a new key is looked at, even a valid one; /healthz is not limited.
        assert client.get("/v1/mdps", headers=bearer(key)).status_code == 429
        assert client.get("/healthz").status_code == 200
        with TestClient(client.app, client=("192.0.2.7", 50000)) as elsewhere:
            assert elsewhere.get("/v1/mdps", headers=bearer(key)).status_code == 200


def test_a_key_already_accepted_keeps_working_from_an_address_a_guesser_shares(settings: Settings) -> None:
    with limited(settings, rate_limit_per_ip=SLOW, rate_limit_per_ip_burst=2) as (client, key):
        assert client.get("/v1/mdps", headers=bearer(key)).status_code == 200
        # A guess answered before authentication (404: no such route) is not taken for an accepted key.
        assert client.get("/v1/nowhere", headers=bearer("mirl_x_early")).status_code == 404
        guesses = [client.get("/v1/mdps", headers=bearer(f"mirl_x_{i}")).status_code for i in range(4)]
        assert guesses == [401, 401, 429, 429]
        assert client.get("/v1/mdps", headers=bearer(key)).status_code == 200
        assert client.get("/v1/mdps", headers=bearer("mirl_x_early")).status_code == 429


def test_a_key_over_its_rate_gets_429_and_other_keys_do_not(settings: Settings) -> None:
    with limited(settings, rate_limit_per_key=SLOW, rate_limit_per_key_burst=3) as (client, key):
        answers = [client.get("/v1/mdps", headers=bearer(key)) for _ in range(5)]
        assert [a.status_code for a in answers] == [200, 200, 200, 429, 429]
        assert int(answers[-1].headers["retry-after"]) >= 1
        assert "with this API key" in answers[-1].json()["detail"]
        with client.app.state.sessionmaker() as session:  # type: ignore[attr-defined]
            other = create_key(session, f"rate-{secrets.token_hex(4)}")
        assert client.get("/v1/mdps", headers=bearer(other)).status_code == 200


def test_a_valid_key_under_the_default_limits_never_sees_429(settings: Settings) -> None:
    with limited(settings) as (client, key):
        assert {client.get("/v1/mdps", headers=bearer(key)).status_code for _ in range(100)} == {200}


def test_a_rate_of_zero_turns_each_limit_off(settings: Settings) -> None:
    off = {
        "rate_limit_per_ip": 0,
        "rate_limit_per_ip_burst": 1,
        "rate_limit_per_key": 0,
        "rate_limit_per_key_burst": 1,
    }
    with limited(settings, **off) as (client, key):
        assert {client.get("/v1/mdps", headers=bearer("nope")).status_code for _ in range(30)} == {401}
        assert {client.get("/v1/mdps", headers=bearer(key)).status_code for _ in range(30)} == {200}


def test_a_rate_and_its_burst_become_the_burst_in_a_window_of_burst_over_rate_seconds() -> None:
    def amount_and_seconds(rate: float, burst: int) -> tuple[int, int]:
        item = window(rate, burst)
        return item.amount, item.get_expiry()

    assert amount_and_seconds(200.0, 400) == (400, 2)  # the per-key default
    assert amount_and_seconds(10.0, 20) == (20, 2)  # the per-address default
    assert amount_and_seconds(SLOW, 5) == (5, 500)
    assert amount_and_seconds(3.0, 10) == (10, 3)  # whole seconds: the nearest window
    assert amount_and_seconds(200.0, 50) == (200, 1)  # a burst below a second's requests is raised to them


def test_a_refused_key_is_let_in_again_after_its_retry_after(settings: Settings) -> None:
    with limited(settings, rate_limit_per_key=1.0, rate_limit_per_key_burst=1) as (client, key):
        answers = [client.get("/v1/mdps", headers=bearer(key)) for _ in range(3)]
        refused = next(a for a in answers if a.status_code == 429)
        time.sleep(int(refused.headers["retry-after"]))
        assert client.get("/v1/mdps", headers=bearer(key)).status_code == 200
