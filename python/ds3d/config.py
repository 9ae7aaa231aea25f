# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""``ds3d.SlamConfig``: the configuration of a SLAM run, by attribute or by key.

One key table (C++ ``ds3d::slam::config_keys()``, docs/configuration.md) serves ``ds3d-slam
--config / --set / --dump-config`` and this class::

    cfg = ds3d.SlamConfig(dynamic="htx")          # keyword = key with '__' or '.' for sections
    cfg.htx.min_score = 0.4                       # attributes by section
    cfg["frontend.orb.num_features"] = 1200       # or keys
    cfg.update({"htx.report_floor": True})
    cfg = ds3d.SlamConfig.from_file("run.yaml")   # YAML or JSON, as ds3d-slam --config
    traj = ds3d.run_slam("path/to/sequence", config=cfg)
"""
import os

from ._ds3d import _SlamConfig, _config_keys

__all__ = ["SlamConfig", "config_keys"]

_KEYS = {name: (kind, help_) for name, kind, help_ in _config_keys()}
# Keyword shortcuts of the `dynamic` section (the CLI's --dynamic / --gate / --weights).
_SHORT = {"dynamic": "dynamic.source", "gate": "dynamic.gate", "weights": "dynamic.weights"}


def config_keys():
    """Every key as a dict ``{name: (type, help)}`` (type: bool, int, number or string)."""
    return dict(_KEYS)


def _to_text(kind, value):
    if kind == "bool" and isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if kind == "number" and isinstance(value, float):
        return repr(value)
    return str(value)


def _from_text(kind, text):
    if kind == "bool":
        return text == "true"
    if kind == "int":
        return int(text)
    if kind == "number":
        return float(text)
    return text


class _Section:
    """Attribute access below a key prefix, e.g. ``cfg.frontend.orb``."""

    def __init__(self, config, prefix):
        object.__setattr__(self, "_config", config)
        object.__setattr__(self, "_prefix", prefix)

    def __getattr__(self, name):
        return self._config._lookup(f"{self._prefix}.{name}")

    def __setattr__(self, name, value):
        self._config[f"{self._prefix}.{name}"] = value

    def __dir__(self):
        p = self._prefix + "."
        return sorted({k[len(p):].split(".")[0] for k in _KEYS if k.startswith(p)})

    def __repr__(self):
        p = self._prefix + "."
        items = ", ".join(f"{k[len(p):]}={self._config[k]!r}" for k in _KEYS if k.startswith(p))
        return f"<{self._prefix}: {items}>"


class SlamConfig:
    """Every parameter of a SLAM run (front-end, dynamic sources, filter, pipeline).

    Keyword arguments set keys: ``SlamConfig(dynamic="htx", gate="motion",
    htx__min_score=0.4)``; ``dynamic``, ``gate`` and ``weights`` are short for the
    ``dynamic.*`` keys. Unknown keys and unparsable values raise ``ValueError`` naming them;
    ranges are checked by :meth:`validate` (and by every run).
    """

    def __init__(self, **keys):
        object.__setattr__(self, "_core", _SlamConfig())
        for k, v in keys.items():
            self[_SHORT.get(k, k.replace("__", "."))] = v

    @classmethod
    def from_file(cls, path, **keys):
        """A config from a YAML or JSON file (as ``ds3d-slam --config``), then ``keys``."""
        cfg = cls()
        cfg._core.apply_file(os.fspath(path))
        for k, v in keys.items():
            cfg[_SHORT.get(k, k.replace("__", "."))] = v
        return cfg

    def _lookup(self, name):
        if name in _KEYS:
            return self[name]
        if any(k.startswith(name + ".") for k in _KEYS):
            return _Section(self, name)
        raise AttributeError(f"ds3d.SlamConfig: no key or section '{name}'")

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        return self._lookup(_SHORT.get(name, name))

    def __setattr__(self, name, value):
        self[_SHORT.get(name, name)] = value

    def __getitem__(self, key):
        if key not in _KEYS:
            raise KeyError(f"ds3d.SlamConfig: unknown key '{key}'")
        return _from_text(_KEYS[key][0], self._core.get(key))

    def __setitem__(self, key, value):
        kind = _KEYS[key][0] if key in _KEYS else "string"
        self._core.set(key, _to_text(kind, value))  # ValueError names an unknown key

    def __iter__(self):
        return iter(_KEYS)

    def __len__(self):
        return len(_KEYS)

    def __contains__(self, key):
        return key in _KEYS

    def __eq__(self, other):
        return isinstance(other, SlamConfig) and self.to_dict() == other.to_dict()

    def __dir__(self):
        return sorted({k.split(".")[0] for k in _KEYS} | set(_SHORT) | {
            "to_dict", "update", "validate", "dump", "copy", "keys", "from_file"})

    def keys(self):
        return list(_KEYS)

    def to_dict(self):
        """``{key: value}`` of every key (bool, int, float or str)."""
        return {k: self[k] for k in _KEYS}

    def update(self, mapping=(), **keys):
        """Sets keys from a mapping of key names (or from keyword arguments, as ``__init__``)."""
        for k, v in dict(mapping).items():
            self[k] = v
        for k, v in keys.items():
            self[_SHORT.get(k, k.replace("__", "."))] = v
        return self

    def validate(self):
        """Raises ValueError naming the first field out of range."""
        self._core.validate()

    def dump(self):
        """Every key with its value and help line, as YAML (``ds3d-slam --dump-config``)."""
        return self._core.dump()

    def copy(self):
        out = SlamConfig()
        object.__setattr__(out, "_core", self._core.copy())
        return out

    def frontend_config(self):
        """The front-end section as a ``ds3d.FrontendConfig`` (for ``ds3d.Slam``)."""
        return self._core.frontend_config()

    def settings(self):
        """``(key, text)`` pairs of every key that differs from the default."""
        base = _SlamConfig()
        return [(k, self._core.get(k)) for k in _KEYS if self._core.get(k) != base.get(k)]

    def __repr__(self):
        changed = ", ".join(f"{k}={self[k]!r}" for k, _ in self.settings())
        return f"ds3d.SlamConfig({changed})"
