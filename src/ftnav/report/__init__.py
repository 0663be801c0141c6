"""ftnav.report"""
