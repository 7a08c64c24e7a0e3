"""A profile's network section: the objects that configure or report the fieldbus
connection, the addressing rules and the LEDs (the Network page reads it).

Part of the device profile model (domain/profile.py): :class:`NetworkSpec` is ``network:`` in
profile.yaml."""

from __future__ import annotations

from pydantic import BaseModel, Field, field_validator

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_base import STRICT, check_address


class NetworkObject(BaseModel):
    """An object that configures or reports the fieldbus connection (the Network page reads it)."""

    model_config = STRICT

    #: The object's address, e.g. ``"0x1017:00"``; it must be an object of the profile.
    object: str
    #: What it tells the engineer about the network, in the manual's terms.
    note: str = Field(min_length=1)
    section: str = Field(min_length=1)

    _address = field_validator("object")(check_address)

    @property
    def address(self) -> ObjectAddress:
        return ObjectAddress.parse(self.object)


class NetworkRule(BaseModel):
    """An addressing rule the engineer must know (switches, defaults, DHCP, ...)."""

    model_config = STRICT

    text: str = Field(min_length=1)
    section: str = Field(min_length=1)


class NetworkLed(BaseModel):
    """One documented state of an LED: its colour or pattern and what it means."""

    model_config = STRICT

    led: str = Field(min_length=1)
    state: str = Field(min_length=1)
    meaning: str = Field(min_length=1)
    section: str = Field(min_length=1)


class NetworkSpec(BaseModel):
    """How the family is addressed on its fieldbus, as its manual says (the Network
    configuration page; docs/profiles.md). Every entry cites its section."""

    model_config = STRICT

    #: One or two sentences: how the family is found and addressed on its fieldbus.
    summary: str = Field(min_length=1)
    section: str = Field(min_length=1)
    #: The objects that configure or report the network, in the order the page lists them.
    objects: tuple[NetworkObject, ...] = ()
    addressing: tuple[NetworkRule, ...] = ()
    leds: tuple[NetworkLed, ...] = ()
