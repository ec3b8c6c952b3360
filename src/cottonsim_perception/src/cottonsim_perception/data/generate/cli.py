"""Parsers of the generate_dataset command line's values (seed lists, image sizes)."""
from __future__ import annotations

from typing import List, Tuple


def parse_seed_list(text: str) -> Tuple[int, ...]:
    """'0-19', '3', '0,2,5-7' or '' -> a tuple of seeds (ValueError naming the bad part)."""
    if text is None:
        return ()
    seeds: List[int] = []
    for part in str(text).replace(" ", "").split(","):
        if not part:
            continue
        try:
            if "-" in part:
                a, b = part.split("-", 1)
                lo, hi = int(a), int(b)
                if lo > hi:
                    raise ValueError
                seeds.extend(range(lo, hi + 1))
            else:
                seeds.append(int(part))
        except ValueError:
            raise ValueError(f"bad seed list part {part!r} in {text!r}: use 'A-B', 'N' or a comma list") from None
    if any(s < 0 for s in seeds):
        raise ValueError(f"seeds must be >= 0, got {text!r}")
    return tuple(dict.fromkeys(seeds))


def parse_image_size(text: str) -> Tuple[int, int]:
    """'640x480' -> (640, 480) (ValueError for anything else)."""
    parts = str(text).lower().split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        w, h = int(parts[0]), int(parts[1])
    except ValueError:
        raise ValueError(f"image size must be 'WxH' like 640x480, got {text!r}") from None
    if w < 16 or h < 16 or w > 4096 or h > 4096:
        raise ValueError(f"image size must be between 16 and 4096 px per side, got {text!r}")
    return w, h
