def write_report(out, sweep=None):
    raise NotImplementedError
