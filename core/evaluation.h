// placeholder until evaluation.h lands
