"""ftnav.fusion"""
