"""Importers that turn real flights recorded by others into the project's flight-log format."""
