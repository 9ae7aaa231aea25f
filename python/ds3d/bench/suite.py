# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Suite files of ds3d-bench (YAML or JSON): parsing, validation and the expansion into cells."""
import glob as globmod
import json
import os
import pathlib
import re

SUITE_KEYS = {"name", "out", "sequences", "configs", "seeds", "eval", "threads_per_run"}
SEQ_KEYS = {"path", "glob", "synth", "name", "groundtruth", "frames", "camera", "seeds", "max_frames",
            "skip_configs"}
SYNTH_KEYS = {"scenario", "frames", "humans", "fps", "parts", "no_noise", "room", "furniture",
              "detection_errors", "args"}
CONFIG_KEYS = {"name", "config", "dynamic", "gate", "weights", "set", "args", "max_frames"}
EVAL_KEYS = {"window", "rpe_delta", "rpe_unit", "plot"}
DEFAULT_EVAL = {"window": 3.0, "rpe_delta": 1.0, "rpe_unit": "s", "plot": True}


class SuiteError(ValueError):
    """A suite file that cannot be used; the message names the file, the entry and the value."""


def _fail(where, msg):
    raise SuiteError(f"ds3d-bench: {where}: {msg}")


def expand_vars(text, where):
    """Replaces ${VAR} (error when unset) and ${VAR:-default} from the environment."""
    def sub(m):
        name, default = m.group(1), m.group(3)
        if name in os.environ and os.environ[name] != "":
            return os.environ[name]
        if default is None:
            _fail(where, f"environment variable {name} is not set (in '{text}'); "
                         f"set it or write ${{{name}:-default}}")
        return default
    return re.sub(r"\$\{([A-Za-z_][A-Za-z0-9_]*)(:-([^}]*))?\}", sub, str(text))


def _resolve(text, base, where):
    p = pathlib.Path(expand_vars(text, where)).expanduser()
    return p if p.is_absolute() else (base / p)


def load_file(path):
    """The mapping of a YAML (.yaml/.yml, needs python3-yaml) or JSON suite file."""
    path = pathlib.Path(path)
    if not path.is_file():
        _fail("suite", f"no such file '{path}'")
    text = path.read_text(encoding="utf-8")
    if path.suffix.lower() in (".yaml", ".yml"):
        try:
            import yaml
        except ImportError:
            _fail(str(path), "YAML suites need python3-yaml (apt-get install python3-yaml); "
                             "or write the suite as JSON")
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as e:
            _fail(str(path), f"not valid YAML: {e}")
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            _fail(str(path), f"not valid JSON: {e}")
    if not isinstance(data, dict):
        _fail(str(path), f"the top level must be a mapping (got {type(data).__name__})")
    return data


def _check_keys(entry, allowed, where):
    if not isinstance(entry, dict):
        _fail(where, f"must be a mapping (got {entry!r})")
    unknown = sorted(set(entry) - allowed)
    if unknown:
        _fail(where, f"unknown key '{unknown[0]}' (allowed: {', '.join(sorted(allowed))})")


def _seeds(value, where):
    if not isinstance(value, list) or not value or not all(isinstance(s, int) and not isinstance(s, bool)
                                                          for s in value):
        _fail(where, f"seeds must be a non-empty list of integers (got {value!r})")
    return list(value)


def _slice(value, where):
    if (not isinstance(value, list) or len(value) != 2 or not all(isinstance(v, int) for v in value)
            or not 0 <= value[0] < value[1]):
        _fail(where, f"frames must be [first, stop) with 0 <= first < stop (got {value!r})")
    return list(value)


def _safe(name):
    return re.sub(r"[^A-Za-z0-9._+-]+", "_", name).strip("_") or "x"


def _recorded(entry, base, where, warnings):
    """Sequence dicts of a path / glob entry (several for a glob; none, with a warning, when absent)."""
    pattern = entry.get("glob", entry.get("path"))
    if not isinstance(pattern, str) or not pattern:
        _fail(where, f"path / glob must be a non-empty string (got {pattern!r})")
    full = str(_resolve(pattern, base, where))
    dirs = sorted(globmod.glob(full)) if ("glob" in entry or globmod.has_magic(full)) else [full]
    dirs = [d for d in dirs if os.path.isdir(d)]
    if not dirs:
        warnings.append(f"{where}: no sequence at '{full}' (set DS3D_DATA_DIR?); skipped")
        return []
    if "name" in entry and len(dirs) > 1:
        _fail(where, f"name is only allowed for a single sequence (glob matched {len(dirs)})")
    out = []
    for d in dirs:
        d = os.path.abspath(d)
        gt = entry.get("groundtruth", "groundtruth.txt")
        gt = str(_resolve(gt, pathlib.Path(d), where))
        seq = {"name": entry.get("name", os.path.basename(d.rstrip("/"))), "kind": "recorded",
               "source": d, "groundtruth": gt, "seeds": [None]}
        if "frames" in entry:
            seq["frames"] = _slice(entry["frames"], where)
        out.append(seq)
    return out


def _synthetic(entry, where, seeds):
    syn = entry["synth"]
    _check_keys(syn, SYNTH_KEYS, f"{where}.synth")
    if not isinstance(syn.get("scenario"), str):
        _fail(f"{where}.synth", f"scenario must be a ds3d-synth scenario name (got {syn.get('scenario')!r})")
    args = ["--scenario", syn["scenario"]]
    for key in ("frames", "humans", "fps", "furniture"):
        if key in syn:
            v = syn[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or v <= 0:
                _fail(f"{where}.synth", f"{key} must be a positive number (got {v!r})")
            args += [f"--{key}", str(v)]
    for key in ("room", "detection_errors"):
        if key in syn:
            args += [f"--{key.replace('_', '-')}", str(syn[key])]
    for key in ("parts", "no_noise"):
        if syn.get(key):
            args.append(f"--{key.replace('_', '-')}")
    extra = syn.get("args", [])
    if not isinstance(extra, list) or not all(isinstance(a, str) for a in extra):
        _fail(f"{where}.synth", f"args must be a list of strings (got {extra!r})")
    seq_seeds = _seeds(entry["seeds"], f"{where}.seeds") if "seeds" in entry else seeds
    return [{"name": entry.get("name", syn["scenario"]), "kind": "synth", "synth_args": args + extra,
             "seeds": seq_seeds}]


def parse_sequences(data, base, seeds, warnings):
    seqs = data.get("sequences")
    if not isinstance(seqs, list) or not seqs:
        _fail("suite", "sequences must be a non-empty list")
    out = []
    for i, entry in enumerate(seqs):
        where = f"sequences[{i}]"
        if isinstance(entry, str):
            entry = {"path": entry}
        _check_keys(entry, SEQ_KEYS, where)
        kinds = [k for k in ("path", "glob", "synth") if k in entry]
        if len(kinds) != 1:
            _fail(where, f"needs exactly one of path, glob, synth (got {kinds or 'none'})")
        found = _synthetic(entry, where, seeds) if kinds[0] == "synth" else _recorded(entry, base, where, warnings)
        skip = entry.get("skip_configs", [])
        if not isinstance(skip, list) or not all(isinstance(n, str) for n in skip):
            _fail(where, f"skip_configs must be a list of configuration names (got {skip!r})")
        for s in found:
            s["camera"] = entry.get("camera")
            s["skip_configs"] = skip
            mf = entry.get("max_frames")
            if mf is not None and (not isinstance(mf, int) or mf < 1):
                _fail(where, f"max_frames must be an integer >= 1 (got {mf!r})")
            s["max_frames"] = mf
        out += found
    return out


def _set_list(value, where):
    if isinstance(value, dict):
        items = []
        for k, v in value.items():
            v = "true" if v is True else "false" if v is False else v
            items.append(f"{k}={v}")
        return items
    if isinstance(value, list) and all(isinstance(v, str) and "=" in v for v in value):
        return list(value)
    _fail(where, f"set must be a mapping of key: value or a list of 'key=value' (got {value!r})")


def config_label(c):
    """A readable default name in the README's style: 'htx --gate evidence --set k=v'."""
    parts = [c.get("dynamic", "default")]
    if c.get("gate"):
        parts.append(f"--gate {c['gate']}")
    if c.get("config"):
        parts.append(f"--config {os.path.basename(str(c['config']))}")
    parts += [f"--set {s}" for s in c.get("_set", [])]
    return " ".join(parts)


def parse_configs(data, base):
    confs = data.get("configs", [{"dynamic": "none"}])
    if not isinstance(confs, list) or not confs:
        _fail("suite", "configs must be a non-empty list")
    out, names = [], set()
    for i, entry in enumerate(confs):
        where = f"configs[{i}]"
        if isinstance(entry, str):
            entry = {"dynamic": entry}
        _check_keys(entry, CONFIG_KEYS, where)
        c = {k: entry[k] for k in ("dynamic", "gate", "weights") if k in entry}
        for k, v in c.items():
            if not isinstance(v, str) or not v:
                _fail(where, f"{k} must be a non-empty string (got {v!r})")
        c["_set"] = _set_list(entry.get("set", {}), where)
        if "config" in entry:
            path = _resolve(entry["config"], base, where)
            if not path.is_file():
                _fail(where, f"config file '{path}' does not exist")
            c["config"] = str(path)
        if "weights" in c:
            c["weights"] = str(_resolve(c["weights"], base, where))
        args = entry.get("args", [])
        if not isinstance(args, list) or not all(isinstance(a, str) for a in args):
            _fail(where, f"args must be a list of strings (got {args!r})")
        c["args"] = args
        mf = entry.get("max_frames")
        if mf is not None and (not isinstance(mf, int) or mf < 1):
            _fail(where, f"max_frames must be an integer >= 1 (got {mf!r})")
        c["max_frames"] = mf
        c["name"] = str(entry.get("name", config_label(c)))
        if c["name"] in names:
            _fail(where, f"config name '{c['name']}' is used twice (give each a distinct name)")
        names.add(c["name"])
        out.append(c)
    return out


def parse_eval(data):
    ev = dict(DEFAULT_EVAL)
    if "eval" in data:
        _check_keys(data["eval"], EVAL_KEYS, "eval")
        ev.update(data["eval"])
    for k in ("window", "rpe_delta"):
        if isinstance(ev[k], bool) or not isinstance(ev[k], (int, float)) or not ev[k] > 0:
            _fail("eval", f"{k} must be > 0 (got {ev[k]!r})")
    if ev["rpe_unit"] not in ("s", "f", "m", "rad", "deg"):
        _fail("eval", f"rpe_unit must be one of s, f, m, rad, deg (got {ev['rpe_unit']!r})")
    return ev


def load_suite(path):
    """Parses a suite file into a dict: name, base, out (or None), sequences, configs, eval,
    threads_per_run, warnings. Raises SuiteError with the entry and the value on bad input."""
    path = pathlib.Path(path).resolve()
    data = load_file(path)
    _check_keys(data, SUITE_KEYS, str(path))
    base = path.parent
    seeds = _seeds(data["seeds"], "seeds") if "seeds" in data else [1]
    warnings = []
    suite = {"name": str(data.get("name", path.stem)), "file": str(path), "base": str(base),
             "out": str(_resolve(data["out"], base, "out")) if "out" in data else None,
             "sequences": parse_sequences(data, base, seeds, warnings),
             "configs": parse_configs(data, base), "eval": parse_eval(data), "warnings": warnings}
    tpr = data.get("threads_per_run", 2)
    if isinstance(tpr, bool) or not isinstance(tpr, int) or tpr < 1:
        _fail("threads_per_run", f"must be an integer >= 1 (got {tpr!r})")
    suite["threads_per_run"] = tpr
    names = {}
    for s in suite["sequences"]:
        if s["name"] in names and names[s["name"]] != s.get("source", s["name"]):
            _fail("sequences", f"two sequences are named '{s['name']}' (give one a name:)")
        names[s["name"]] = s.get("source", s["name"])
    return suite


def sequence_dir_name(seq, seed):
    return _safe(seq["name"] if seed is None else f"{seq['name']}_{seed}")


def cell_id(seq, config, seed):
    """Folder name of one cell: sequence[_seed]__config, filesystem-safe."""
    return f"{sequence_dir_name(seq, seed)}__{_safe(config['name'])}"
