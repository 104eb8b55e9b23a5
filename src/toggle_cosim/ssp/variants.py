"""An SSP's variants, as SSP 1.0.1 defines them (section 3, Packaging): `SystemStructure.ssd`, the
default, and every other `*.ssd` at the archive's top level, each named by its `name` attribute.

Checked before any variant is read further, each failure one SspError line: every root SSD
within bounds and valid against the schemas of its SSP version, 1.0 or 2.0 (`checks`); its name
and its System's usable as folder names (`SAFE_NAME`: results land in OUT/<system>/<variant>/)
and the variants' names unique, ignoring case; not an SSP of an earlier toggle-cosim (stacked
bindings); no two .ssv files of one component with one set name (a master that picks sets by
name, Ecos, could not tell them apart).
"""

from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

from toggle_cosim.ssp import layout
from toggle_cosim.ssp.bindings import BindingBudget, bindings_of
from toggle_cosim.ssp.checks import Element, SspError, open_archive, parse_member

__all__ = ["SAFE_NAME", "Variant", "check_set_names", "choose", "root_ssds", "variants"]

NS = layout.NAMESPACES
SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,199}\Z")  # a scenario's name: a folder name anywhere


@dataclass(frozen=True)
class Variant:
    """A root SSD: its member, its name and its parsed root."""

    member: str
    name: str
    ssd: Element


def root_ssds(archive: zipfile.ZipFile, path: Path) -> list[Variant]:
    """Every root SSD, the default first, each parsed and checked; names unique and safe."""
    names = archive.namelist()
    if layout.SSD_MEMBER not in names:
        raise SspError(f"{path}: no {layout.SSD_MEMBER} in the archive (an SSP needs one at its top level)")
    others = sorted(n for n in names if "/" not in n and n.endswith(layout.SSD_SUFFIX) and n != layout.SSD_MEMBER)
    found: list[Variant] = []
    seen: dict[str, str] = {}
    for member in (layout.SSD_MEMBER, *others):
        where = f"{path}: {member}"
        ssd = parse_member(archive, member, "ssd", where)
        if any(a.get("type") == layout.OLD_ANNOTATION_TYPE for a in ssd.iterfind("ssd:Annotations/ssc:Annotation", NS)):
            raise SspError(
                f"{where}: written by an earlier toggle-cosim, with one binding per parameter set on each component, "
                "which SSP 1.0 applies all at once (write it again with toggle-cosim ssp: one root SSD per variant)"
            )
        name = ssd.get("name")
        for what, text in (("name", name), ("System name", ssd.find("ssd:System", NS).get("name"))):
            if not SAFE_NAME.match(text):
                raise SspError(
                    f"{where}: the {what} {text!r} cannot name a results folder (use letters, digits, _ . - "
                    "and no more than 200 of them, not starting with . or -)"
                )
        other = seen.setdefault(name.casefold(), member)
        if other != member:
            raise SspError(
                f"{where}: the variant name {name!r} is also {other}'s (names are compared ignoring case; "
                "give each root SSD its own name)"
            )
        found.append(Variant(member, name, ssd))
    return found


def check_set_names(variants_found: list[Variant], archive: zipfile.ZipFile, path: Path) -> None:
    """No two .ssv files bound to one component (by name) carry the same set name."""
    sources: dict[tuple[str, str | None], str] = {}
    for variant in variants_found:
        where = f"{path}: {variant.member}"
        budget = BindingBudget(where)
        for component in variant.ssd.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
            for binding in bindings_of(component, archive, str(path), where, budget):
                if binding.source == "inline":
                    continue
                key = (component.get("name"), binding.set_name)
                other = sources.setdefault(key, binding.source)
                if other != binding.source:
                    raise SspError(
                        f"{path}: {other} and {binding.source} both hold the parameter set {binding.set_name!r} of "
                        f"component {key[0]!r} (a master that picks sets by name cannot tell them apart; rename one)"
                    )


def variants(path: Path) -> tuple[str, ...]:
    """The names of the SSP's variants, the default (SystemStructure.ssd) first."""
    with open_archive(Path(path)) as archive:
        return tuple(variant.name for variant in root_ssds(archive, Path(path)))


def choose(found: list[Variant], asked: str | None, path: Path) -> Variant:
    """The variant `asked` names (None: the default, the first): a root SSD's name first, else
    its member's file name (`no_friction.ssd`); a file name without .ssd is no variant's name."""
    if asked is None:
        return found[0]
    for variant in found:
        if asked == variant.name:
            return variant
    for variant in found:
        if asked == variant.member:
            return variant
    raise SspError(
        f"{path}: no variant {asked!r} (choose one of {', '.join(v.name for v in found)} with --variant; "
        f"the default is {found[0].name}, {layout.SSD_MEMBER})"
    )
