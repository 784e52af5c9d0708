"""The config reference in docs/cli.md, generated from the schema.

``python -m jaxclear.cli._reference docs/cli.md`` rewrites the text between the
``<!-- settings-reference:start/end -->`` and ``<!-- description-reference:start/end -->`` markers;
``tests/test_cli.py`` fails when the page is not current.
"""

import re
import sys
from pathlib import Path

from ._mechanism_config import markdown_reference as description_reference
from ._settings import markdown_reference as settings_reference

BLOCKS = {"settings-reference": settings_reference, "description-reference": description_reference}


def fill(text: str) -> str:
    """``text`` with every marked block replaced by the current reference.

    Raises:
        ValueError: a pair of markers is missing.
    """
    for name, generate in BLOCKS.items():
        pattern = re.compile(rf"(<!-- {name}:start -->\n).*?(<!-- {name}:end -->)", re.DOTALL)
        if not pattern.search(text):
            raise ValueError(f"markers <!-- {name}:start --> ... <!-- {name}:end --> not found")
        text = pattern.sub(lambda m, g=generate: m.group(1) + "\n" + g() + "\n" + m.group(2), text)
    return text


if __name__ == "__main__":  # pragma: no cover
    path = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/cli.md")
    path.write_text(fill(path.read_text()))
