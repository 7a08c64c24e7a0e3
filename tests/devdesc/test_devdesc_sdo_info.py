"""The profile built from an EtherCAT slave's SDO Information (devdesc/sdo_info.py, issue 46):
the slave's objects, the CiA 402 knowledge of cia402-ethercat over them (ETG.1000.6 §5.6.3)."""

from __future__ import annotations

from servodesk.devdesc.sdo_info import profile_from_sdo_info, sdo_info_profile_id
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.ethercat import OdEntryInfo, OdObjectInfo
from servodesk.domain.paramset import configurable
from servodesk.domain.profile import Access, DeviceProfile, ObjectSpec, PdoMapping
from servodesk.domain.profile_loader import ProfileCatalog, check_profile

#: Object access of Get Entry Description: read in every state, + written, + TxPDO-mappable.
RO, RW, RO_TX, RW_RX = 0x07, 0x3F, 0x87, 0x7F


def _var(index: int, name: str, dt: DataType, access: int) -> OdObjectInfo:
    return OdObjectInfo(index, name, 7, int(dt), (OdEntryInfo(0, name, int(dt), dt.bits, access),))


OBJECTS = (
    _var(0x6040, "Controlword", DataType.UNSIGNED16, RW_RX),
    _var(0x6041, "Statusword", DataType.UNSIGNED16, RO_TX),
    # The Synapticon sample's type: unsigned where CiA 402 says INTEGER32.
    _var(0x6064, "Position Value", DataType.UNSIGNED32, RO_TX),
    _var(0x6081, "Profile velocity", DataType.UNSIGNED32, RW),
    _var(0x2345, "Vendor tuning gain", DataType.UNSIGNED32, RW),
    OdObjectInfo(
        0x1018,
        "Identity",
        9,
        0,
        (
            OdEntryInfo(0, "SubIndex 000", 5, 8, RO),
            OdEntryInfo(1, "Vendor ID", 7, 32, RO),
            OdEntryInfo(2, "Product Code", 7, 32, RO),
        ),
    ),
    # A DEFTYPE (object code 5) has no place in the model: left out and said so.
    OdObjectInfo(0x0007, "UDINT", 5, 7, ()),
)


def _built() -> tuple[DeviceProfile, DeviceProfile]:
    base = ProfileCatalog().get("cia402-ethercat")
    p = profile_from_sdo_info(
        OBJECTS,
        base,
        vendor_id=0x22D2,
        product_code=0x201,
        revision=0x0A,
        device_name="SOMANET",
        where="1 on sdt0",
    )
    return base, p


def _spec(p: DeviceProfile, index: int, sub: int = 0) -> ObjectSpec:
    spec = p.spec(ObjectAddress(index, sub))
    assert spec is not None, f"{index:04X}h:{sub:02X}"
    return spec


def test_the_profile_has_the_slaves_objects_and_keeps_the_cia402_knowledge() -> None:
    base, p = _built()
    assert p.id == sdo_info_profile_id(0x22D2, 0x201) == "ethercat-000022d2-00000201-sdoinfo"
    assert check_profile(p) == []
    # Exactly the slave's objects: 6060h (cia402-ethercat has it) is not listed by the slave.
    assert sorted(p.entries) == [0x1018, 0x2345, 0x6040, 0x6041, 0x6064, 0x6081]
    assert p.modes == base.modes and p.pdo.kind == "ethercat"
    vendor = _spec(p, 0x2345)
    assert vendor.access is Access.RW and vendor.group == "manufacturer"
    assert vendor.address in {s.address for s in configurable(p)}
    # The base's meaning of 6081h (units) is kept; 6064h keeps its unit and process flag but
    # takes the slave's data type.
    assert _spec(p, 0x6081).unit == _spec(base, 0x6081).unit is not None
    pos = _spec(p, 0x6064)
    assert pos.data_type is DataType.UNSIGNED32 and pos.process and pos.pdo_mapping is PdoMapping.TX
    assert _spec(p, 0x6040).access is Access.RWW
    assert _spec(p, 0x1018, 2).name == "Product Code"
    # Where it came from, and what was left out.
    assert p.description is not None
    assert "SDO Information" in p.description and "1 on sdt0" in p.description
    assert "0007h (object code 5)" in p.description
    # Never chosen by an identity match over an imported ESI of the same drive.
    assert p.identity.vendor_id is None
