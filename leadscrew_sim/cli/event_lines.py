"""The ``events:`` lines of ``simulate``, ``resim`` and ``info``: one line per event."""

#: Events printed at most; the rest are counted.
MAX_EVENTS = 50


def print_events(events, limit=MAX_EVENTS):
    """Print ``events:`` and one line per event (time [s], text), at most ``limit`` of them."""
    print(f'events: {len(events) if events else "none"}')
    for e in events[:limit]:
        print(f'  {e.time:12.6f} s  {e.text}')
    if len(events) > limit:
        print(f'  ... {len(events) - limit} more')
