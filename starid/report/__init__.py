"""Pictures and tables from result frames."""
