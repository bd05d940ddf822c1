class CutAlongLineEnv:
    pass
