"""Cases as data: a PSS/E raw + dyr pair (or a built-in case name) becomes a `Case`:
the network (`System`) and its device groups, one group per dyr model, each group
an array over its devices.

Built-in cases (`BUILTIN`) live in `smibjax/grid/cases/` as raw + dyr files. Which
generator a record belongs to is the (bus number, machine id) pair, as in PSS/E.
Conventions: a GENCLS with H = 0 is an infinite bus (PSS/E's convention), held at its
power-flow voltage (its source impedance is ignored: the bus voltage is fixed); a
generator with a CSVGN1 record is an SVC (PSS/E models SVCs as generators), not a
machine.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import replace
from importlib import resources
from pathlib import Path

import numpy as np

from .._errors import ParameterError
from .loop import Case

__all__ = [
    "BUILTIN",
    "load_case",
    "build_case",
    "case_files",
    "SUPPORTED",
    "andes_swing",
]

# name -> (raw file, dyr file) in smibjax/grid/cases/
BUILTIN = {
    "kundur": ("kundur.raw", "kundur.dyr"),
    "kundur-gencls": ("kundur.raw", "kundur_gencls.dyr"),
    "kundur-nopss": ("kundur.raw", "kundur_nopss.dyr"),
    "kundur-synex": ("kundur.raw", "kundur_synex.dyr"),
    "ieee39": ("ieee39.raw", "ieee39.dyr"),
    "ieee39-pss": ("ieee39.raw", "ieee39_pss.dyr"),
    "ieee39-gencls": ("ieee39.raw", "ieee39_gencls.dyr"),
    "smib": ("smib.raw", "smib.dyr"),
    "smib-gencls": ("smib.raw", "smib_gencls.dyr"),
    # ANDES 2.0's public cases, as shipped (cases/README.md; issue 45)
    "ieee14": ("ieee14.raw", "ieee14.dyr"),
    "wecc179": ("wecc179.raw", "wecc179.dyr"),
    "npcc": ("npcc.raw", "npcc.dyr"),
    "nordic44": ("nordic44.raw", "nordic44.dyr"),
    # issues 45, 46: Texas A&M's synthetic ACTIVSg2000 (ERCOT footprint) with its
    # dynamics, from NREL-Sienna/PowerSystemsTestData (cases/README.md)
    "activsg2000": ("activsg2000.raw", "activsg2000.dyr"),
    # issue 47: NREL's reduced WECC 240-bus system with 37 renewable plants
    "wecc240": ("wecc240.raw", "wecc240.dyr"),
}

# issue 46 (ACTIVSg2000): how built-in cases are read beyond the default. Its raw file
# is PSS/E's solved case with generators at their reactive limits
# (`to_system(..., var_limited=True)`: the power flow returns the file's own
# voltages), and its dyr file has no dynamic data for 98 in-service generators (its
# wind and solar plants): `build_case(..., unmodelled_as_load=True)`
BUILTIN_OPTIONS = {"activsg2000": {"var_limited": True, "unmodelled_as_load": True}}

MACHINES = ("GENCLS", "GENTRA", "GENROU")
MACHINES += ("GENROE", "GENSAL", "GENSAE")  # issue 45
EXCITERS = ("SEXS", "IEEEX1", "EXDC2", "EXST1", "SYNEX")
# issue 45: more PSS/E exciters, and the load compensator IEEEVC (it writes the
# voltage the exciter regulates; grouped here as part of the excitation system)
EXCITERS += ("ESST3A", "ESDC2A", "SCRX", "IEEET2", "IEEEVC", "ESDC1A", "IEEET1")
# issue 45, part 2: more PSS/E exciters
EXCITERS += ("ESST4B", "ESST1A", "EXAC1", "ESAC1A", "EXAC2", "EXPIC1", "ESAC6A")
EXCITERS += ("DC4B",)
STABILIZERS = ("IEEEST", "STAB1")
GOVERNORS = ("TGOV1",)
# governors and stabilizers of issue 45
STABILIZERS += ("ST2CUT", "STAB2A", "PSS2A", "PSS2B")
GOVERNORS += ("IEEEG1", "HYGOV", "IEESGO", "GAST")
GOVERNORS += ("GGOV1",)  # issue 45 (GGOV1)
SVCS = ("CSVGN1",)
SUPPORTED = MACHINES + EXCITERS + STABILIZERS + GOVERNORS + SVCS
# issue 47: inverter-based resources (converter, electrical and plant controllers)
RENEWABLES = ("REGCA1", "REECB1", "REPCA1")
SUPPORTED += RENEWABLES


class CaseError(ParameterError):
    """A case that cannot be built (one line: what and where)."""


def case_files(name: str) -> tuple[Path, Path]:
    """The raw and dyr files of a built-in case."""
    if name not in BUILTIN:
        raise CaseError(
            f"case {name!r} is not built in: choose one of {', '.join(BUILTIN)} "
            "or give a .raw file with --dyr"
        )
    root = resources.files("smibjax.grid") / "cases"
    raw, dyr = BUILTIN[name]
    return Path(str(root / raw)), Path(str(root / dyr))


def load_case(
    name_or_raw: str | Path,
    dyr: str | Path | None = None,
    *,
    skip_unsupported: bool = False,
) -> Case:
    """A built-in case by name, or a raw file with its dyr file. With
    `skip_unsupported`, dyr records of models smibjax does not have are skipped with
    one warning per model (`psse.read_dyr`) instead of refused: a machine whose
    exciter or governor is skipped keeps its field voltage or mechanical power at
    the operating point's, and a machine whose machine record is skipped is refused
    as having no dynamic data."""
    from .psse import read_dyr, read_raw, to_system

    if dyr is None and str(name_or_raw) in BUILTIN:
        raw_path, dyr_path = case_files(str(name_or_raw))
        name = str(name_or_raw)
        opts = BUILTIN_OPTIONS.get(name, {})
    else:
        if dyr is None:
            if not (str(name_or_raw).endswith(".raw") or Path(name_or_raw).is_file()):
                case_files(str(name_or_raw))  # raises: not a built-in name
            raise CaseError(f"{name_or_raw}: a raw file needs its dyr file (--dyr)")
        raw_path, dyr_path = Path(name_or_raw), Path(dyr)
        name = raw_path.stem
        opts = {}
    system = to_system(read_raw(raw_path), var_limited=opts.get("var_limited", False))
    records = read_dyr(dyr_path, skip_unsupported=skip_unsupported)
    return build_case(
        system,
        records,
        name=name,
        unmodelled_as_load=opts.get("unmodelled_as_load", False),
    )


def _gen_key_index(system):
    gens = system.generators
    buses = np.asarray(system.buses.number)[np.asarray(gens.bus)]
    idents = gens.ident or tuple("1" for _ in buses)
    return {
        (int(b), str(i).strip()): k
        for k, (b, i) in enumerate(zip(buses, idents, strict=True))
    }


def _group(cls, gens, params, **extra):
    """A device group from dyr parameter dicts (PSS/E names) at generator positions."""
    if hasattr(cls, "from_params"):
        return cls.from_params(gens, params, **extra)
    raise CaseError(f"{cls.__name__} cannot be built from dyr records")


def _model_class(model: str):
    from . import devices

    return getattr(devices, model)


# issue 45 (exciters): a refused controller record named by its file and line
def _located(cls, entries):
    """The controller group `cls` from its (generator position, dyr record)
    entries. A refused parameter (`ParameterError`, one line naming the model, the
    parameter and what is allowed) is raised again prefixed with the file and line
    of the first record that is refused on its own."""
    from .._validate import ParameterError

    def build(ents):
        return cls.from_params([g for g, _ in ents], [r.params for _, r in ents])

    try:
        return build(entries)
    except ParameterError:
        for g, r in entries:
            try:
                build([(g, r)])
            except ParameterError as one:
                raise ParameterError(f"{r.file}:{r.line}: {one}") from None
        raise


def _as_negative_loads(system, records):
    """`system` with each in-service generator that has no machine record among
    `records` (nor an SVC record) turned into a negative load at its bus (identifier
    'G' + its machine id) and given status 0 (issue 46, ACTIVSg2000)."""
    import equinox as eqx

    keys = _gen_key_index(system)
    modelled = {
        keys[(int(r.bus), str(r.ident).strip())]
        for r in records
        if r.model in MACHINES + SVCS and (int(r.bus), str(r.ident).strip()) in keys
    }
    gens = system.generators
    status = np.array(gens.status, dtype=float)  # a copy: `system` stays as given
    ids = gens.ident or tuple("1" for _ in status)
    moved = [k for k in range(len(status)) if status[k] > 0 and k not in modelled]
    if not moved:
        return system
    ld = system.loads
    gbus = np.asarray(gens.bus)[moved]
    loads = type(ld)(
        bus=np.concatenate([np.asarray(ld.bus), gbus]),
        p=np.concatenate([np.asarray(ld.p), -np.asarray(gens.p)[moved]]),
        q=np.concatenate([np.asarray(ld.q), -np.asarray(gens.q)[moved]]),
        ident=tuple(ld.ident) + tuple(f"G{str(ids[k]).strip()}" for k in moved)
        if ld.ident
        else (),
    )
    status[moved] = 0.0
    system = eqx.tree_at(lambda s: s.loads, system, loads)
    return eqx.tree_at(lambda s: s.generators.status, system, status)


def build_case(
    system, records, name: str = "", *, unmodelled_as_load: bool = False
) -> Case:
    """A `Case` from a `System` and dyr records (`psse.read_dyr`). An in-service
    generator without a machine record is refused, or, with `unmodelled_as_load`,
    becomes a negative constant-power load -(p + j q) at its bus and is taken out of
    service (PSS/E's GNET activity; `_as_negative_loads`): the power flow of a solved
    raw file returns the same voltages (its p and q are the file's solution), and
    the simulation holds it as a constant admittance, like every load."""
    if unmodelled_as_load:
        system = _as_negative_loads(system, records)
    keys = _gen_key_index(system)
    by_model = defaultdict(list)
    for r in records:
        key = (int(r.bus), str(r.ident).strip())
        if key not in keys:
            raise CaseError(
                f"{r.file}:{r.line}: {r.model} for generator {key[1]!r} at bus "
                f"{key[0]}: no such generator in the raw file"
            )
        by_model[r.model].append((keys[key], r))
    gens = system.generators
    mbase = np.asarray(gens.mbase)
    zsource = gens.source_impedance()
    machines, controllers, svcs, sources = [], [], [], []
    have_machine = set()
    for model in MACHINES:
        entries = by_model.get(model, [])
        if model == "GENCLS":
            inf = [(g, r) for g, r in entries if r.params["H"] == 0]
            entries = [(g, r) for g, r in entries if r.params["H"] != 0]
            sources += [g for g, _ in inf]
            have_machine |= {g for g, _ in inf}
        if not entries:
            continue
        pos = [g for g, _ in entries]
        for g, r in entries:
            if g in have_machine:
                raise CaseError(
                    f"{r.file}:{r.line}: a second machine record for generator "
                    f"{r.ident!r} at bus {r.bus}"
                )
            have_machine.add(g)
        params = [r.params for _, r in entries]
        cls = _model_class(model)
        machines.append(
            cls.from_params(
                pos,
                params,
                mbase=mbase[pos],
                zsource=zsource[pos],
                f_base=system.f_base,
            )
        )
    for model in SVCS:
        entries = by_model.get(model, [])
        if entries:
            pos = [g for g, _ in entries]
            have_machine |= set(pos)
            bus = np.asarray(gens.bus)[pos]
            params = [dict(r.params, MBASE=float(mbase[g])) for g, r in entries]
            svcs.append(_model_class(model).from_params(bus, params))
    # issue 47: the renewables, one injector group
    renewables = _renewables(system, by_model, f_base=system.f_base)
    if renewables is not None:
        have_machine |= {int(g) for g in np.asarray(renewables.gen)}
    for model in STABILIZERS + EXCITERS + GOVERNORS:
        entries = by_model.get(model, [])
        if not entries:
            continue
        for g, r in entries:
            if g not in have_machine:
                raise CaseError(
                    f"{r.file}:{r.line}: {model} for generator {r.ident!r} at bus "
                    f"{r.bus} has no machine record"
                )
        cls = _model_class(model)
        if getattr(cls, "needs_mbase", False):  # issue 45 (GGOV1): powers on Trate
            entries = [
                (g, replace(r, params={**r.params, "MBASE": float(mbase[g])}))
                for g, r in entries
            ]
        controllers.append(_located(cls, entries))
    unknown = sorted(set(by_model) - set(SUPPORTED))
    if unknown:
        raise CaseError(
            f"unsupported dyr model {unknown[0]}: supported are {', '.join(SUPPORTED)}"
        )
    status = np.asarray(gens.status)
    nb = np.asarray(system.buses.number)[np.asarray(gens.bus)]
    for k in range(len(status)):
        if status[k] > 0 and k not in have_machine:
            raise CaseError(
                f"generator {gens.ident[k] if gens.ident else '1'!r} at bus {nb[k]} "
                "is in service but has no machine record in the dyr file"
            )
    extra = {} if renewables is None else {"injectors": (renewables,)}
    return Case(
        system=system,
        machines=tuple(machines),
        controllers=tuple(controllers),
        svcs=tuple(svcs),
        sources=tuple(sorted(sources)),
        name=name,
        **extra,
    )


def andes_swing(case: Case) -> Case:
    """`case` with ANDES's swing equation, 2 H d omega/dt = Pm - Te - D omega, on
    every machine group that has PSS/E's, (Pm - D omega)/(1 + omega) - Te (GENROU,
    GENROE, GENSAL, GENSAE: their `speed_factor`; `devices._dq.swing`): for
    comparisons with ANDES 2.0, which has no speed factor. PSS/E's own results follow
    the speed factor (docs/validation-psse.md)."""
    import dataclasses

    machines = tuple(
        dataclasses.replace(m, speed_factor=False) if hasattr(m, "speed_factor") else m
        for m in case.machines
    )
    return dataclasses.replace(case, machines=machines)


# issue 47: inverter-based resources
def _renewables(system, by_model, f_base):
    """The `Renewable` injector group of the REGCA1 records (with their REECB1 and
    REPCA1 records, by generator), or None. A REECB1 without its generator's
    REGCA1, or a REPCA1 without its REECB1, is refused (one line)."""
    from .devices.renewable import Renewable

    conv = {g: r for g, r in by_model.get("REGCA1", [])}
    elec = {}
    for g, r in by_model.get("REECB1", []):
        if g not in conv:
            raise CaseError(
                f"{r.file}:{r.line}: REECB1 for generator {r.ident!r} at bus {r.bus} "
                "has no REGCA1 record (the converter it commands)"
            )
        elec[g] = r
    plant = {}
    for g, r in by_model.get("REPCA1", []):
        if g not in elec:
            raise CaseError(
                f"{r.file}:{r.line}: REPCA1 for generator {r.ident!r} at bus {r.bus} "
                "has no REECB1 record (the electrical controller it commands)"
            )
        plant[g] = r
    if not conv:
        return None
    pos = sorted(conv)
    gens = system.generators

    def build(ps):
        return Renewable.from_params(
            gen=ps,
            bus=np.asarray(gens.bus)[ps],
            mbase=np.asarray(gens.mbase)[ps],
            regc=[conv[g].params for g in ps],
            reec=[elec[g].params if g in elec else None for g in ps],
            repc=[plant[g].params if g in plant else None for g in ps],
            f_base=f_base,
        )

    try:
        return build(pos)
    except ParameterError:
        for g in pos:  # name the file and line of the record refused on its own
            try:
                build([g])
            except ParameterError as one:
                recs = [r for r in (conv[g], elec.get(g), plant.get(g)) if r]
                r = next((r for r in recs if str(one).startswith(r.model)), recs[0])
                raise ParameterError(f"{r.file}:{r.line}: {one}") from None
        raise
