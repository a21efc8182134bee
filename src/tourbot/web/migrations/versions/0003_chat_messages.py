"""The text channel between the visitor in control of a robot and the people on site (staff, the
robot's own screen): WebFAIR's tele-conferencing in its simplest form.

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "chat_messages",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("robot_id", sa.Integer, sa.ForeignKey("robots.id"), nullable=False),
        sa.Column("session_id", sa.Integer, sa.ForeignKey("visitor_sessions.id"), nullable=False),
        sa.Column("sender", sa.String(16), nullable=False),
        sa.Column("text", sa.String(500), nullable=False),
        sa.Column("at", sa.Float, nullable=False),
    )
    op.create_index("ix_chat_messages_robot", "chat_messages", ["robot_id", "id"])


def downgrade() -> None:
    op.drop_index("ix_chat_messages_robot", "chat_messages")
    op.drop_table("chat_messages")
