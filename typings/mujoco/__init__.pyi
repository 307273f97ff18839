# MuJoCo's Python bindings ship no type information; this stub makes every
# attribute of the module `Any` so pyright checks our code, not theirs.
from typing import Any

def __getattr__(name: str) -> Any: ...
