"""Pictures for the docs, and the headless animation renderer."""
