"""Helpers shared by the test files (a library module: it holds no tests)."""
from __future__ import annotations


def edited(monkeypatch, module, name: str, old: str, new: str) -> None:
    """module.name, a text such as a bench's scene template, with `old` replaced by `new` for this test; `old`
    must be there (a template that changed fails here, not as a test that silently runs the old size)."""
    text = getattr(module, name)
    assert old in text, f"{module.__name__}.{name} no longer holds {old!r}"
    monkeypatch.setattr(module, name, text.replace(old, new))
