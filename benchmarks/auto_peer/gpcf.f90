!---------------------------------------------------------------------------------------------
! Granular plane Couette flow (gPCF) for AUTO-07p: the steady boundary-value problem of
! physics.md section 3, written from that specification (not generated from contin).
!
! t = y + 1/2 in [0, 1];  state U = (u, T, Q, nu, M):
!   u'  = S / (f2 sqrt T)
!   T'  = -H^2 Q / (f4 sqrt T)
!   Q'  = S^2 / (f2 sqrt T) - f5 T^(3/2)
!   nu' = (-H^3 G nu - f1 T') / (f1'(nu) T)        (G = Fr^-2; G = 0: f1 T = const)
!   M'  = nu
! No-slip, adiabatic walls and the mass constraint (6 conditions, NBC = 6):
!   u(0) = -1/2, u(1) = 1/2, Q(0) = Q(1) = 0, M(0) = 0, M(1) = nubar.
! Parameters: PAR(1) = H, PAR(2) = S (the unknown shear stress: free in every run),
!   PAR(3) = nubar, PAR(4) = e, PAR(5) = G5 = 1e5 G, PAR(6) = nu_m (chi_JJ = 1/(1 - (nu/nu_m)^(1/3))),
!   (G = Fr^-2 ~ 1e-5 on the fold curves: scaled by 1e5 so that its steps and Newton updates are
!   commensurate with those of H, otherwise AUTO's fold continuation diverges at its first step),
!   PAR(9) = Phi = nu(t = 1) (order parameter, set by PVLS).
! Closures (physics.md 1.2, LSJC in Alam's f-notation, eta = (1 + e)/2):
!   f1 = nu (1 + 4 eta nu chi),   f5 = (12/sqrt(pi)) (1 - e^2) nu^2 chi,
!   f2 = (5 sqrt(pi)/96) [1/(eta(2-eta)chi) + (8/5)(3eta-1)nu/(2-eta) + (64/25) eta ((3eta-2)/(2-eta) + 12/pi) nu^2 chi],
!   f4 = (25 sqrt(pi)/16) [1/(eta(41-33eta)chi) + (12/5)(1+eta(4eta-3)) nu/(41-33eta)
!                          + (16/25) eta (9 eta (4eta-3)/(41-33eta) + 4/pi) nu^2 chi].
! Guard: AUTO accepts NaN residuals as converged (its convergence test compares with
! EPSL/EPSU, and every comparison with NaN is false), so outside T > 0, 0 < nu < nu_m the
! right-hand side is set to a large finite value instead of evaluating sqrt/chi there.
!---------------------------------------------------------------------------------------------

SUBROUTINE CLOSURES(NU, E, NUM, F1, F1N, F2, F4, F5)
  ! Complex arithmetic so that FUNC can differentiate by the complex step (exact Jacobian).
  IMPLICIT NONE
  COMPLEX(KIND=8), INTENT(IN) :: NU
  DOUBLE PRECISION, INTENT(IN) :: E, NUM
  COMPLEX(KIND=8), INTENT(OUT) :: F1, F1N, F2, F4, F5
  DOUBLE PRECISION, PARAMETER :: PI = 3.14159265358979323846D0
  DOUBLE PRECISION :: ETA
  COMPLEX(KIND=8) :: S, CHI, CHIN
  ETA = (1.0D0 + E) / 2.0D0
  S = (NU / NUM)**(1.0D0 / 3.0D0)
  CHI = 1.0D0 / (1.0D0 - S)
  CHIN = CHI * CHI * S / (3.0D0 * NU)
  F1 = NU * (1.0D0 + 4.0D0 * ETA * NU * CHI)
  F1N = 1.0D0 + 8.0D0 * ETA * NU * CHI + 4.0D0 * ETA * NU * NU * CHIN
  F2 = (5.0D0 * SQRT(PI) / 96.0D0) * (1.0D0 / (ETA * (2.0D0 - ETA) * CHI) &
       + (8.0D0 / 5.0D0) * (3.0D0 * ETA - 1.0D0) * NU / (2.0D0 - ETA) &
       + (64.0D0 / 25.0D0) * ETA * ((3.0D0 * ETA - 2.0D0) / (2.0D0 - ETA) + 12.0D0 / PI) * NU * NU * CHI)
  F4 = (25.0D0 * SQRT(PI) / 16.0D0) * (1.0D0 / (ETA * (41.0D0 - 33.0D0 * ETA) * CHI) &
       + (12.0D0 / 5.0D0) * (1.0D0 + ETA * (4.0D0 * ETA - 3.0D0)) * NU / (41.0D0 - 33.0D0 * ETA) &
       + (16.0D0 / 25.0D0) * ETA * (9.0D0 * ETA * (4.0D0 * ETA - 3.0D0) / (41.0D0 - 33.0D0 * ETA) + 4.0D0 / PI) &
         * NU * NU * CHI)
  F5 = (12.0D0 / SQRT(PI)) * (1.0D0 - E * E) * NU * NU * CHI
END SUBROUTINE CLOSURES

SUBROUTINE RHS(U, H, S, E, G, NUM, F)
  ! The right-hand side in complex arithmetic (physics.md section 3, header of this file)
  IMPLICIT NONE
  COMPLEX(KIND=8), INTENT(IN) :: U(5), H, S, G
  DOUBLE PRECISION, INTENT(IN) :: E, NUM
  COMPLEX(KIND=8), INTENT(OUT) :: F(5)
  COMPLEX(KIND=8) :: T, Q, NU, F1, F1N, F2, F4, F5, RT, DT
  T = U(2)
  Q = U(3)
  NU = U(4)
  CALL CLOSURES(NU, E, NUM, F1, F1N, F2, F4, F5)
  RT = SQRT(T)
  DT = -H * H * Q / (F4 * RT)
  F(1) = S / (F2 * RT)
  F(2) = DT
  F(3) = S * S / (F2 * RT) - F5 * T * RT
  F(4) = (-H**3 * G * NU - F1 * DT) / (F1N * T)
  F(5) = NU
END SUBROUTINE RHS

SUBROUTINE FUNC(NDIM, U, ICP, PAR, IJAC, F, DFDU, DFDP)
  ! F, and with IJAC >= 1 the exact DFDU and DFDP (H, S, G5) by the complex step
  ! dF/dx = Im F(x + i h) / h, h = 1e-30 (no cancellation, so exact to rounding).
  IMPLICIT NONE
  INTEGER, INTENT(IN) :: NDIM, ICP(*), IJAC
  DOUBLE PRECISION, INTENT(IN) :: U(NDIM), PAR(*)
  DOUBLE PRECISION, INTENT(OUT) :: F(NDIM)
  DOUBLE PRECISION, INTENT(INOUT) :: DFDU(NDIM, NDIM), DFDP(NDIM, *)
  DOUBLE PRECISION, PARAMETER :: HC = 1.0D-30
  COMPLEX(KIND=8) :: UC(5), FC(5), H, S, G
  DOUBLE PRECISION :: E, NUM
  INTEGER :: J
  E = PAR(4)
  NUM = PAR(6)
  IF (.NOT. (U(2) > 0.0D0 .AND. U(4) > 0.0D0 .AND. U(4) < NUM)) THEN
    F(:) = 1.0D10   ! outside the physical range (see the header): never "converged"
    IF (IJAC >= 1) DFDU(:, :) = 0.0D0
    IF (IJAC >= 1) THEN
      DO J = 1, NDIM
        DFDU(J, J) = 1.0D0
      END DO
    END IF
    IF (IJAC >= 2) DFDP(:, 1:5) = 0.0D0
    RETURN
  END IF
  UC = CMPLX(U(1:5), 0.0D0, KIND=8)
  H = CMPLX(PAR(1), 0.0D0, KIND=8)
  S = CMPLX(PAR(2), 0.0D0, KIND=8)
  G = CMPLX(1.0D-5 * PAR(5), 0.0D0, KIND=8)
  CALL RHS(UC, H, S, E, G, NUM, FC)
  F = DBLE(FC)
  IF (IJAC == 0) RETURN
  DO J = 1, NDIM
    UC(J) = CMPLX(U(J), HC, KIND=8)
    CALL RHS(UC, H, S, E, G, NUM, FC)
    DFDU(:, J) = AIMAG(FC) / HC
    UC(J) = CMPLX(U(J), 0.0D0, KIND=8)
  END DO
  IF (IJAC == 1) RETURN
  CALL RHS(UC, CMPLX(PAR(1), HC, KIND=8), S, E, G, NUM, FC)
  DFDP(:, 1) = AIMAG(FC) / HC
  CALL RHS(UC, H, CMPLX(PAR(2), HC, KIND=8), E, G, NUM, FC)
  DFDP(:, 2) = AIMAG(FC) / HC
  CALL RHS(UC, H, S, E, CMPLX(1.0D-5 * PAR(5), 1.0D-5 * HC, KIND=8), NUM, FC)
  DFDP(:, 5) = AIMAG(FC) / HC
  DFDP(:, 3) = 0.0D0
  DFDP(:, 4) = 0.0D0
END SUBROUTINE FUNC

SUBROUTINE STPNT(NDIM, U, PAR, T)
  ! Uniform shear at H = PAR(1): u = y, T0 = f2/f5, Q = 0, nu = nubar, M = nubar t, S0 = f2 sqrt(T0)
  IMPLICIT NONE
  INTEGER, INTENT(IN) :: NDIM
  DOUBLE PRECISION, INTENT(INOUT) :: U(NDIM), PAR(*)
  DOUBLE PRECISION, INTENT(IN) :: T
  COMPLEX(KIND=8) :: F1, F1N, F2, F4, F5
  DOUBLE PRECISION :: T0
  CHARACTER(LEN=256) :: TEXT
  INTEGER :: LENGTH, STATUS
  ! AUTO applies the constants file's PAR only after STPNT, so the start values come from the
  ! environment: GPCF_PAR = "H nubar e G5 nu_m" (python -m benchmarks.auto_peer sets it).
  PAR(1:6) = (/ 2.0D0, 0.0D0, 0.3D0, 0.8D0, 0.0D0, 0.65D0 /)
  CALL GET_ENVIRONMENT_VARIABLE('GPCF_PAR', TEXT, LENGTH, STATUS)
  IF (STATUS == 0 .AND. LENGTH > 0) READ (TEXT, *) PAR(1), PAR(3), PAR(4), PAR(5), PAR(6)
  CALL CLOSURES(CMPLX(PAR(3), 0.0D0, KIND=8), PAR(4), PAR(6), F1, F1N, F2, F4, F5)
  T0 = DBLE(F2 / F5)
  PAR(2) = DBLE(F2) * SQRT(T0)
  U(1) = T - 0.5D0
  U(2) = T0
  U(3) = 0.0D0
  U(4) = PAR(3)
  U(5) = PAR(3) * T
END SUBROUTINE STPNT

SUBROUTINE BCND(NDIM, PAR, ICP, NBC, U0, U1, FB, IJAC, DBC)
  IMPLICIT NONE
  INTEGER, INTENT(IN) :: NDIM, ICP(*), NBC, IJAC
  DOUBLE PRECISION, INTENT(IN) :: PAR(*), U0(NDIM), U1(NDIM)
  DOUBLE PRECISION, INTENT(OUT) :: FB(NBC)
  DOUBLE PRECISION, INTENT(INOUT) :: DBC(NBC, *)
  FB(1) = U0(1) + 0.5D0
  FB(2) = U1(1) - 0.5D0
  FB(3) = U0(3)
  FB(4) = U1(3)
  FB(5) = U0(5)
  FB(6) = U1(5) - PAR(3)
  IF (IJAC == 0) RETURN
  ! DBC(:, 1:NDIM) = d/dU0, (NDIM+1:2 NDIM) = d/dU1, then d/dPAR
  DBC(1:NBC, 1:2 * NDIM + 6) = 0.0D0
  DBC(1, 1) = 1.0D0
  DBC(2, NDIM + 1) = 1.0D0
  DBC(3, 3) = 1.0D0
  DBC(4, NDIM + 3) = 1.0D0
  DBC(5, 5) = 1.0D0
  DBC(6, NDIM + 5) = 1.0D0
  DBC(6, 2 * NDIM + 3) = -1.0D0
END SUBROUTINE BCND

SUBROUTINE ICND(NDIM, PAR, ICP, NINT, U, UOLD, UDOT, UPOLD, FI, IJAC, DINT)
  INTEGER NDIM, ICP(*), NINT, IJAC
  DOUBLE PRECISION PAR(*), U(NDIM), UOLD(NDIM), UDOT(NDIM), UPOLD(NDIM), FI(NINT), DINT(NINT, *)
END SUBROUTINE ICND

SUBROUTINE FOPT
END SUBROUTINE FOPT

SUBROUTINE PVLS(NDIM, U, PAR)
  ! PAR(9) = Phi = nu at the top wall (t = 1), the order parameter of physics.md section 3
  IMPLICIT NONE
  INTEGER, INTENT(IN) :: NDIM
  DOUBLE PRECISION, INTENT(IN) :: U(NDIM)
  DOUBLE PRECISION, INTENT(INOUT) :: PAR(*)
  DOUBLE PRECISION, EXTERNAL :: GETP
  PAR(9) = GETP('BV1', 4, U)
END SUBROUTINE PVLS
