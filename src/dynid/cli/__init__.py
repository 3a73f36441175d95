"""The `dynid` command."""
