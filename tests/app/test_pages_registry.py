"""Pages are declared one way (``PAGES = (PageSpec(...),)``): unique titles and orders, and the
trackers a page drives are registered trackers, each driven by at most one page."""

from __future__ import annotations

from collections import Counter

from app.pages import discover_pages, page_for_tracker
from engine.trackers import available_trackers


def test_page_orders_and_titles_are_unique() -> None:
    pages = discover_pages()
    assert len(pages) >= 7
    orders = Counter(p.order for p in pages)
    assert not [o for o, n in orders.items() if n > 1], f"pages share an order: {orders}"
    assert [p.title for p in pages][:3] == ["Live", "Keyframes", "Presenter"]


def test_declared_trackers_exist_and_have_one_page_each() -> None:
    known = set(available_trackers())
    claimed: Counter[str] = Counter()
    for page in discover_pages():
        assert set(page.trackers) <= known, f"{page.title} drives unknown {page.trackers}"
        claimed.update(page.trackers)
    assert not [t for t, n in claimed.items() if n > 1], claimed
    assert page_for_tracker("ptz").title == "PTZ"  # type: ignore[union-attr]
    assert page_for_tracker("beacon-slam").title == "Beacons"  # type: ignore[union-attr]
    assert page_for_tracker("dense") is None  # driven from Live, like every pose tracker
