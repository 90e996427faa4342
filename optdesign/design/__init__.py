"""Design layer: the public verbs (validate -> formulate -> solve -> verify -> result)."""
