"""Network endpoints a scenario names: an IPv4 address with an optional UDP port."""

import ipaddress


def parse_endpoint(text: str, what: str) -> tuple[str, int | None]:
    """(IPv4 address, port or None) of "HOST" or "HOST:PORT".

    Args:
        text: what the scenario says, e.g. "192.168.1.20" or "127.0.0.1:5501".
        what: the setting it comes from, for the message ("allowed sender").

    Raises:
        ValueError: naming `what` and `text`, for a host that is not an IPv4 address or a
            port outside [1, 65535].
    """
    host, _, port = str(text).strip().partition(":")
    try:
        address = str(ipaddress.IPv4Address(host))
        number = int(port) if port else None
    except ValueError:
        raise ValueError(
            f"{what} {text!r} is not HOST or HOST:PORT (IPv4, e.g. 192.168.1.20 or 127.0.0.1:5501)"
        ) from None
    if number is not None and not 1 <= number <= 65535:
        raise ValueError(f"{what} {text!r}: port must be in [1, 65535]")
    return address, number
