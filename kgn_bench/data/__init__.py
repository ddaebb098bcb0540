"""The Primitive Shape dataset: generation, file format and (later) training data."""
