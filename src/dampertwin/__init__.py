"""dampertwin."""
