"""ftnav.plot"""
