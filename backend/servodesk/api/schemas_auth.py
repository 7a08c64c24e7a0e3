"""Request and response models of the login, account, login-session and API-token routes
(api/routes/auth.py; docs/api.md "Users")."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from servodesk.domain.roles import Role
from servodesk.services.users import MAX_PASSWORD, MIN_PASSWORD


class LoginRequest(BaseModel):
    user: str = Field(min_length=1, max_length=64)
    password: str = Field(min_length=1, max_length=1024)


class MeOut(BaseModel):
    user: str
    role: str
    rights: list[str] = Field(description="The rights of the role (docs/security.md, Roles)")
    mode: str = Field(description='"single-user" (loopback, no login) or "login"')
    session: str | None = Field(description="The login session's id (null: token, single-user)")
    idle_timeout_s: float = Field(description="A login session unused this long ends")


class UserOut(BaseModel):
    name: str
    role: str
    disabled: bool
    created: float


#: services/users.py's rules, in the schema too ("local" is the single-user mode's name).
NewPassword = Annotated[str, Field(min_length=MIN_PASSWORD, max_length=MAX_PASSWORD)]


class UserCreate(BaseModel):
    model_config = ConfigDict(regex_engine="python-re")  # The look-ahead below.

    name: str = Field(pattern=r"^(?!local$)[A-Za-z0-9][A-Za-z0-9._@-]{0,63}$")
    role: Role
    password: NewPassword


class UserPatch(BaseModel):
    role: Role | None = None
    disabled: bool | None = None
    password: NewPassword | None = None


class LoginSessionOut(BaseModel):
    id: str
    user: str
    address: str
    created: float
    last_seen: float
    websockets: int = Field(description="Open WebSockets of this session (closed when it ends)")


class TokenOut(BaseModel):
    id: str
    user: str
    label: str
    created: float
    last_used: float | None


class TokenCreate(BaseModel):
    label: str = Field(default="", max_length=100)


class TokenCreated(TokenOut):
    secret: str = Field(
        description="The token, shown this once: send it as Authorization: Bearer <secret>"
    )
