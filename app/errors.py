"""The load error every model-file path raises (kept apart so readers need not import loaders)."""


class SceneLoadError(Exception):
    """A file that cannot become a scene; the message is meant for the person who picked it."""
