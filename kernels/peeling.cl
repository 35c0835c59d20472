/* peeling.cl: placeholder, filled in by the method's implementation. */
