"""The GPX and RTZ documents are serialised once (``maps.export._common.xml_document``): the bytes of
``ElementTree.tostring(root, encoding="utf-8", xml_declaration=True)``, which passes every piece of the
document through an encoder of its own (0.05 s of a plan's exports), whatever the text holds."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from maps.export._common import xml_document


def test_xml_document_is_what_elementtree_writes():
    root = ET.Element("gpx", version="1.1", xmlns="http://www.topografix.com/GPX/1/1")
    trk = ET.SubElement(root, "trk")
    ET.SubElement(trk, "name").text = "Kustaanmiekka → 060° <zig-zag> & \"turn\" 'à' ß"
    for k in range(3):
        p = ET.SubElement(trk, "trkpt", lat=f"{60.1 + k:.7f}", lon="24.9", note='a < b & c > "d"\n')
        ET.SubElement(p, "time").text = f"2026-06-01T08:00:0{k}Z"
    ET.SubElement(trk, "desc").text = "vessel \udcff"  # a non-UTF-8 byte of a command line, as Python decodes argv
    ET.indent(root, space=" ")
    assert xml_document(root) == ET.tostring(root, encoding="utf-8", xml_declaration=True)


def test_thruster_names_follow_the_profile_file(tmp_path, monkeypatch):
    """The crew files name the azimuth thrusters from the built-in profile of the plan's ship, read once per
    content of its file: an edited file is read again, never a stale name, even when the edit keeps the file's
    length and modification time (an mtime-and-size key answered the old names)."""
    import os
    from types import SimpleNamespace

    import primitives.ship as ship
    from maps.export._common import _thruster_labels

    text = (ship.PROFILE_DIR / "full-scale.toml").read_text()
    path = tmp_path / "full-scale.toml"
    path.write_text(text)
    monkeypatch.setattr(ship, "PROFILE_DIR", tmp_path)
    plan = SimpleNamespace(ship="full-scale", input_names=["n1", "alpha1", "n2", "alpha2"])
    assert _thruster_labels(plan) == ["bow thruster", "stern thruster"]
    st = path.stat()
    path.write_text(text.replace('name = "bow"', 'name = "fwd"'))  # same length
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))  # same time, as an edit within the clock's granularity
    assert path.stat().st_size == st.st_size
    assert _thruster_labels(plan) == ["fwd thruster", "stern thruster"]
    path.write_text(text.replace('name = "bow"', 'name = "fore"'))
    assert _thruster_labels(plan) == ["fore thruster", "stern thruster"]
