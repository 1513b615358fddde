"""The MakeHuman development set: characters built at run time from MakeHuman's CC0 base mesh and targets
(``../shared/data/makehuman``), each with its true landmarks and unit (:mod:`scripts.devset.makehuman`)."""
