"""``tail-beam`` subcommands of the identification package."""
