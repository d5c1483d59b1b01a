from .distiller import CBNetDistiller

__all__ = ['CBNetDistiller']
