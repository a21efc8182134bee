"""Exhibits get a short summary: what the robot says on arrival and the on-board screen shows.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("exhibits") as batch:
        batch.add_column(sa.Column("summary", sa.String(400), nullable=False, server_default=""))


def downgrade() -> None:
    with op.batch_alter_table("exhibits") as batch:
        batch.drop_column("summary")
